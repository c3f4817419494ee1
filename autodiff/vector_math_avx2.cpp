// AVX2 + FMA unit of vector_math.h (8 float lanes, 4 double lanes for pow). Built with
// -mavx2 -mfma -mno-avx512f (autodiff/CMakeLists.txt) and called only when the CPU has both.
#include "autodiff/vector_math_kernels.h"
#include "autodiff/vector_math_lanes.h"

namespace sl::vm::detail {

namespace {
// Internal linkage, so this unit's instantiations (built for its instruction set) stay its own.
struct V : Lanes<float, 8> {};
struct VD : Lanes<double, 4> {};
}  // namespace

SL_VM_DEFINE_TABLE(avx2_table, V, VD)

}  // namespace sl::vm::detail
