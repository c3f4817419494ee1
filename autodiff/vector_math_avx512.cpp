// AVX-512 (F, DQ, BW, VL) unit of vector_math.h (16 float lanes, 8 double lanes for pow). Built
// with -mavx512f -mavx512dq -mavx512bw -mavx512vl -mfma (autodiff/CMakeLists.txt) and called
// only when the CPU has all of them.
#include "autodiff/vector_math_kernels.h"
#include "autodiff/vector_math_lanes.h"

namespace sl::vm::detail {

namespace {
// Internal linkage, so this unit's instantiations (built for its instruction set) stay its own.
struct V : Lanes<float, 16> {};
struct VD : Lanes<double, 8> {};
}  // namespace

SL_VM_DEFINE_TABLE(avx512_table, V, VD)

}  // namespace sl::vm::detail
