// Scalar fallback of vector_math.h: the same operations as the SIMD units, one lane at a time.
#include "autodiff/vector_math_kernels.h"
#include "autodiff/vector_math_lanes.h"

namespace sl::vm::detail {

namespace {
// Internal linkage, so this unit's instantiations (built for its instruction set) stay its own.
struct V : Lanes<float, 1> {};
struct VD : Lanes<double, 1> {};
}  // namespace

SL_VM_DEFINE_TABLE(scalar_table, V, VD)

}  // namespace sl::vm::detail
