// Outputs and gradients of the nn ops and grid_sample against PyTorch 1.13 on the fixtures that
// scripts/make_torch_fixtures.py committed to tests/fixtures/torch/: each case stores its
// inputs, the output, a fixed weight R and the gradients of sum(out · R).
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "autodiff/ops.h"
#include "nn/functional/conv.h"
#include "nn/functional/depthwise_conv.h"
#include "nn/functional/linear.h"
#include "nn/functional/normalization.h"
#include "nn/functional/pooling.h"
#include "nn/functional/upsample.h"
#include "support/fixture_reader.h"

namespace sl::test {
using nn::avg_pool2d;
using nn::avg_pool3d;
using nn::batch_norm;
using nn::conv2d;
using nn::conv3d;
using nn::depthwise_conv2d;
using nn::global_avg_pool;
using nn::group_norm;
using nn::instance_norm;
using nn::linear;
using nn::max_pool2d;
using nn::max_pool3d;
using nn::upsample_bilinear2d;
using nn::upsample_nearest2d;
using nn::upsample_nearest3d;
using nn::upsample_trilinear3d;

namespace {
using nlohmann::json;

std::string fixture_path(const std::string& file) {
  return std::string(STREETLIGHT_SOURCE_DIR) + "/tests/fixtures/torch/" + file;
}

// |ours - torch| <= 1e-4·|torch| + 1e-5·max|torch| (the floor scales with the tensor).
void expect_close(const Tensor& ours, const Tensor& torch, const std::string& what) {
  ASSERT_TRUE(ours.defined()) << what << " is undefined";
  ASSERT_EQ(ours.shape(), torch.shape()) << what;
  const auto a = ours.to_vector(), b = torch.to_vector();
  double scale = 0;
  for (double v : b) scale = std::max(scale, std::abs(v));
  const double floor = 1e-5 * std::max(scale, 1.0);
  for (size_t i = 0; i < a.size(); ++i)
    ASSERT_LE(std::abs(a[i] - b[i]), 1e-4 * std::abs(b[i]) + floor)
        << what << " element " << i << ": ours " << a[i] << " vs torch " << b[i];
}

template <size_t D>
std::array<int64_t, D> arr(const json& j) {
  std::array<int64_t, D> a{};
  for (size_t i = 0; i < D; ++i) a[i] = j.at(i).get<int64_t>();
  return a;
}

using OpFn = std::function<Tensor(const Fixture&, const std::string& name, const json& c, std::map<std::string, Tensor>& in)>;

// Loads the case's inputs as leaves that require grad, runs `op`, and compares the output
// and every stored gradient.
void run_family(const std::string& file, const OpFn& op) {
  const Fixture f = sl::test::read_fixture(fixture_path(file));
  const json cases = json::parse(f.metadata.at("cases"));
  ASSERT_FALSE(cases.empty());
  for (const json& c : cases) {
    const std::string name = c.at("name").get<std::string>();
    SCOPED_TRACE(name);
    std::map<std::string, Tensor> in;
    for (const char* k : {"x", "w", "b", "grid"}) {
      const std::string key = name + "." + k;
      if (f.has(key)) {
        in[k] = f.at(key).clone();
        if (f.has(name + ".grad." + k)) in[k].set_requires_grad(true);
      }
    }
    Tensor out = op(f, name, c, in);
    expect_close(out, f.at(name + ".out"), name + ".out");
    backward(out, f.at(name + ".R"));
    for (const auto& [k, t] : in)
      if (f.has(name + ".grad." + k)) expect_close(t.grad(), f.at(name + ".grad." + k), name + ".grad." + k);
  }
}

Tensor get(const std::map<std::string, Tensor>& in, const char* k) {
  auto it = in.find(k);
  return it == in.end() ? Tensor() : it->second;
}

TEST(TorchFixtures, ConvolutionMatchesPyTorch) {
  run_family("conv.safetensors", [](const Fixture&, const std::string&, const json& c, auto& in) {
    if (c.at("op") == "conv2d")
      return conv2d(in["x"], in["w"], get(in, "b"), arr<2>(c["stride"]), arr<2>(c["padding"]), arr<2>(c["dilation"]));
    return conv3d(in["x"], in["w"], get(in, "b"), arr<3>(c["stride"]), arr<3>(c["padding"]), arr<3>(c["dilation"]));
  });
}

// F.conv2d with groups = C.
TEST(TorchFixtures, DepthwiseConvolutionMatchesPyTorch) {
  run_family("depthwise_conv.safetensors", [](const Fixture&, const std::string&, const json& c, auto& in) {
    return depthwise_conv2d(in["x"], in["w"], get(in, "b"), arr<2>(c["stride"]), arr<2>(c["padding"]));
  });
}

TEST(TorchFixtures, UpsamplingMatchesPyTorch) {
  run_family("upsample.safetensors", [](const Fixture&, const std::string&, const json& c, auto& in) {
    const std::string op = c.at("op");
    const int64_t s = c.at("scale");
    if (op == "upsample_nearest2d") return upsample_nearest2d(in["x"], s);
    if (op == "upsample_nearest3d") return upsample_nearest3d(in["x"], s);
    if (op == "upsample_bilinear2d") return upsample_bilinear2d(in["x"], s, c.at("align_corners"));
    return upsample_trilinear3d(in["x"], s, c.at("align_corners"));
  });
}

TEST(TorchFixtures, PoolingMatchesPyTorch) {
  run_family("pool.safetensors", [](const Fixture&, const std::string&, const json& c, auto& in) {
    const std::string op = c.at("op");
    if (op == "global_avg_pool") return global_avg_pool(in["x"]);
    if (op == "max_pool2d") return max_pool2d(in["x"], arr<2>(c["kernel"]), arr<2>(c["stride"]), arr<2>(c["padding"]));
    if (op == "avg_pool2d") return avg_pool2d(in["x"], arr<2>(c["kernel"]), arr<2>(c["stride"]), arr<2>(c["padding"]));
    if (op == "max_pool3d") return max_pool3d(in["x"], arr<3>(c["kernel"]), arr<3>(c["stride"]), arr<3>(c["padding"]));
    return avg_pool3d(in["x"], arr<3>(c["kernel"]), arr<3>(c["stride"]), arr<3>(c["padding"]));
  });
}

TEST(TorchFixtures, NormalizationMatchesPyTorchIncludingRunningStats) {
  run_family("norm.safetensors", [](const Fixture& f, const std::string& name, const json& c, auto& in) {
    const std::string op = c.at("op");
    const double eps = c.at("eps");
    if (op == "group_norm") return group_norm(in["x"], c.at("groups"), get(in, "w"), get(in, "b"), eps);
    if (op == "instance_norm") return instance_norm(in["x"], get(in, "w"), get(in, "b"), eps);
    Tensor rm = f.at(name + ".running_mean").clone(), rv = f.at(name + ".running_var").clone();
    Tensor y = batch_norm(in["x"], rm, rv, in["w"], in["b"], c.at("training"), c.at("momentum"), eps);
    expect_close(rm, f.at(name + ".running_mean_after"), name + ".running_mean_after");
    expect_close(rv, f.at(name + ".running_var_after"), name + ".running_var_after");
    return y;
  });
}

TEST(TorchFixtures, LinearMatchesPyTorch) {
  run_family("linear.safetensors", [](const Fixture&, const std::string&, const json&, auto& in) {
    return linear(in["x"], in["w"], get(in, "b"));
  });
}

TEST(TorchFixtures, GridSampleMatchesPyTorch) {
  run_family("grid_sample.safetensors", [](const Fixture&, const std::string&, const json& c, auto& in) {
    const GridPadding pad = c.at("padding") == "border" ? GridPadding::Border : GridPadding::Zeros;
    if (c.at("op") == "grid_sample_2d") return grid_sample_2d(in["x"], in["grid"], c.at("align_corners"), pad);
    return grid_sample_3d(in["x"], in["grid"], c.at("align_corners"), pad);
  });
}

}  // namespace
}  // namespace sl::test
