// A program outside Streetlight, built against the installed package (see CMakeLists.txt): it
// differentiates through a small network and a placed object, and prints what it measured.
// Exit 0 when every check holds, 1 otherwise.
#include <cmath>
#include <cstdio>

#include "autodiff/gradcheck.h"
#include "autodiff/ops.h"
#include "render/object_placement.h"
#include "render/primitives.h"
#include "util/math.h"

using sl::render::Bounds3;
using sl::render::make_box;
using sl::render::Mesh;
using sl::render::placed_mesh;
using sl::render::Placement;

int main() {
  using namespace sl;
  // Autodiff: d/dw mean(tanh(x·w)²), checked against float64 finite differences.
  const Tensor x = Tensor::uniform({8, 3}, -1, 1, /*seed=*/2).to(DType::F64);
  const GradcheckResult g = gradcheck(
      [&](const TensorList& in) { return mean(square(tanh(matmul(x, in[0])))); },
      {Tensor::normal({3, 1}, 0, 0.5, /*seed=*/1).to(DType::F64)});
  // Render: a 1 m box turned a quarter turn (yaw +90°: its +X points down −Z).
  const Mesh box = make_box({0.0f, 0.0f, -0.25f}, {1.0f, 0.5f, 0.25f});
  Placement p;
  p.x_m = 2.0;
  p.z_m = -10.0;
  p.yaw_deg = 90.0;
  const Bounds3 b = placed_mesh(box, p).bounds();
  const bool placed_ok = std::abs(b.lo.z - (-11.0f)) < 1e-5f && std::abs(b.hi.z - (-10.0f)) < 1e-5f &&
                         std::abs(b.lo.x - 1.75f) < 1e-5f && std::abs(b.hi.x - 2.25f) < 1e-5f;
  std::printf("gradcheck %s (max abs error %.3g); placed box z [%.3f, %.3f]; pi %.6f\n", g.ok ? "ok" : "FAILED",
              g.max_abs_error, b.lo.z, b.hi.z, kPi);
  return g.ok && placed_ok ? 0 : 1;
}
