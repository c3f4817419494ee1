// Outputs and gradients of the nn ops and grid_sample against PyTorch 1.13 on the fixtures of
// tests/fixtures/torch/ (support/torch_fixture.h).
#include <gtest/gtest.h>

#include "autodiff/ops.h"
#include "nn/functional/conv.h"
#include "nn/functional/depthwise_conv.h"
#include "nn/functional/linear.h"
#include "nn/functional/normalization.h"
#include "nn/functional/pooling.h"
#include "nn/functional/upsample.h"
#include "support/torch_fixture.h"

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

TEST(TorchFixtures, ConvolutionMatchesPyTorch) {
  run_torch_family("conv.safetensors", [](const Fixture&, const std::string&, const json& c, auto& in) {
    if (c.at("op") == "conv2d")
      return conv2d(in["x"], in["w"], optional_input(in, "b"), json_array<2>(c["stride"]),
                    json_array<2>(c["padding"]), json_array<2>(c["dilation"]));
    return conv3d(in["x"], in["w"], optional_input(in, "b"), json_array<3>(c["stride"]),
                  json_array<3>(c["padding"]), json_array<3>(c["dilation"]));
  });
}

// F.conv2d with groups = C.
TEST(TorchFixtures, DepthwiseConvolutionMatchesPyTorch) {
  run_torch_family("depthwise_conv.safetensors", [](const Fixture&, const std::string&, const json& c, auto& in) {
    return depthwise_conv2d(in["x"], in["w"], optional_input(in, "b"), json_array<2>(c["stride"]), json_array<2>(c["padding"]));
  });
}

TEST(TorchFixtures, UpsamplingMatchesPyTorch) {
  run_torch_family("upsample.safetensors", [](const Fixture&, const std::string&, const json& c, auto& in) {
    const std::string op = c.at("op");
    const int64_t s = c.at("scale");
    if (op == "upsample_nearest2d") return upsample_nearest2d(in["x"], s);
    if (op == "upsample_nearest3d") return upsample_nearest3d(in["x"], s);
    if (op == "upsample_bilinear2d") return upsample_bilinear2d(in["x"], s, c.at("align_corners"));
    return upsample_trilinear3d(in["x"], s, c.at("align_corners"));
  });
}

TEST(TorchFixtures, PoolingMatchesPyTorch) {
  run_torch_family("pool.safetensors", [](const Fixture&, const std::string&, const json& c, auto& in) {
    const std::string op = c.at("op");
    if (op == "global_avg_pool") return global_avg_pool(in["x"]);
    if (op == "max_pool2d") return max_pool2d(in["x"], json_array<2>(c["kernel"]), json_array<2>(c["stride"]), json_array<2>(c["padding"]));
    if (op == "avg_pool2d") return avg_pool2d(in["x"], json_array<2>(c["kernel"]), json_array<2>(c["stride"]), json_array<2>(c["padding"]));
    if (op == "max_pool3d")
      return max_pool3d(in["x"], json_array<3>(c["kernel"]), json_array<3>(c["stride"]), json_array<3>(c["padding"]));
    return avg_pool3d(in["x"], json_array<3>(c["kernel"]), json_array<3>(c["stride"]), json_array<3>(c["padding"]));
  });
}

TEST(TorchFixtures, NormalizationMatchesPyTorchIncludingRunningStats) {
  run_torch_family("norm.safetensors", [](const Fixture& f, const std::string& name, const json& c, auto& in) {
    const std::string op = c.at("op");
    const double eps = c.at("eps");
    if (op == "group_norm") return group_norm(in["x"], c.at("groups"), optional_input(in, "w"), optional_input(in, "b"), eps);
    if (op == "instance_norm") return instance_norm(in["x"], optional_input(in, "w"), optional_input(in, "b"), eps);
    Tensor rm = f.at(name + ".running_mean").clone(), rv = f.at(name + ".running_var").clone();
    Tensor y = batch_norm(in["x"], rm, rv, in["w"], in["b"], c.at("training"), c.at("momentum"), eps);
    expect_close_to_torch(rm, f.at(name + ".running_mean_after"), name + ".running_mean_after");
    expect_close_to_torch(rv, f.at(name + ".running_var_after"), name + ".running_var_after");
    return y;
  });
}

TEST(TorchFixtures, LinearMatchesPyTorch) {
  run_torch_family("linear.safetensors", [](const Fixture&, const std::string&, const json&, auto& in) {
    return linear(in["x"], in["w"], optional_input(in, "b"));
  });
}

TEST(TorchFixtures, GridSampleMatchesPyTorch) {
  run_torch_family("grid_sample.safetensors", [](const Fixture&, const std::string&, const json& c, auto& in) {
    const GridPadding pad = c.at("padding") == "border" ? GridPadding::Border : GridPadding::Zeros;
    if (c.at("op") == "grid_sample_2d") return grid_sample_2d(in["x"], in["grid"], c.at("align_corners"), pad);
    return grid_sample_3d(in["x"], in["grid"], c.at("align_corners"), pad);
  });
}

}  // namespace
}  // namespace sl::test
