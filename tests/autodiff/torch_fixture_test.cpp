// The autodiff library's pointwise and reducing ops against PyTorch 1.13 on
// tests/fixtures/torch/pointwise.safetensors (support/torch_fixture.h): outputs and gradients,
// over the ranges the networks and losses reach (exp to ±20, sigmoid and softplus to ±40, log over
// 14 decades, log1p and expm1 near 0) and with broadcasting in the binary ops. The vectorised
// kernels (autodiff/vector_math.h) approximate exp, log, tanh and atan2 by polynomials; this is
// where they meet an independent implementation.
#include <gtest/gtest.h>

#include "autodiff/ops.h"
#include "support/torch_fixture.h"

namespace sl::test {
namespace {
using nlohmann::json;

std::vector<int64_t> axes_of(const json& c) { return c.at("axes").get<std::vector<int64_t>>(); }

Tensor pointwise_op(const json& c, TorchInputs& in) {
  const std::string op = c.at("op");
  const Tensor& x = in["x"];
  if (op == "neg") return neg(x);
  if (op == "exp") return exp(x);
  if (op == "log") return log(x);
  if (op == "log1p") return log1p(x);
  if (op == "expm1") return expm1(x);
  if (op == "sqrt") return sqrt(x);
  if (op == "square") return square(x);
  if (op == "abs") return abs(x);
  if (op == "pow_scalar") return pow_scalar(x, c.at("p"));
  if (op == "clamp") return clamp(x, c.at("lo"), c.at("hi"));
  if (op == "relu") return relu(x);
  if (op == "leaky_relu") return leaky_relu(x, c.at("slope"));
  if (op == "elu") return elu(x, c.at("alpha"));
  if (op == "sigmoid") return sigmoid(x);
  if (op == "softplus") return softplus(x);
  if (op == "tanh") return tanh(x);
  if (op == "sin") return sin(x);
  if (op == "cos") return cos(x);
  if (op == "acos") return acos(x);
  if (op == "add") return add(x, in["y"]);
  if (op == "sub") return sub(x, in["y"]);
  if (op == "mul") return mul(x, in["y"]);
  if (op == "div") return div(x, in["y"]);
  if (op == "pow") return pow(x, in["y"]);
  if (op == "minimum") return minimum(x, in["y"]);
  if (op == "maximum") return maximum(x, in["y"]);
  if (op == "atan2") return atan2(x, in["y"]);  // torch.atan2(input, other) = atan2(y = input, x = other)
  if (op == "sum") return sum(x, axes_of(c), c.at("keepdim"));
  if (op == "mean") return mean(x, axes_of(c), c.at("keepdim"));
  if (op == "max") return max(x, axes_of(c), c.at("keepdim"));
  if (op == "min") return min(x, axes_of(c), c.at("keepdim"));
  if (op == "logsumexp") return logsumexp(x, c.at("axis"), c.at("keepdim"));
  if (op == "normalize") return normalize(x, c.at("axis"));
  ADD_FAILURE() << "the fixture names an op this test does not know: " << op;
  return Tensor();
}

TEST(TorchFixtures, PointwiseAndReducingOpsMatchPyTorch) {
  size_t cases = 0;
  run_torch_family("pointwise.safetensors", [&](const Fixture&, const std::string&, const json& c, auto& in) {
    ++cases;
    return pointwise_op(c, in);
  });
  EXPECT_EQ(cases, 36u) << "every case of the fixture ran";
}

}  // namespace
}  // namespace sl::test
