// Writes the seeds of tests/fuzz/corpus that our own writers produce (valid checkpoints,
// safetensors, GLB and image files). Disabled: run it by hand after a format change,
//   build/tests/fuzz_tests --gtest_also_run_disabled_tests --gtest_filter='FuzzSeeds.*'
// Hand-made edge cases and crash regressions sit beside these files and are not rewritten.
#include <gtest/gtest.h>

#include <filesystem>

#include "data/image_io.h"
#include "nn/checkpoint.h"
#include "nn/modules/linear.h"
#include "nn/optim.h"
#include "render/gltf_writer.h"
#include "render/primitives.h"

using sl::data::Transfer;
using sl::data::write_depth;
using sl::data::write_image;
using sl::render::make_box;
using sl::render::write_glb;

namespace sl::test {

namespace {

std::string corpus(const std::string& target, const std::string& name) {
  const std::filesystem::path dir = std::filesystem::path(STREETLIGHT_SOURCE_DIR) / "tests/fuzz/corpus" / target;
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

TEST(FuzzSeeds, DISABLED_WriteSeedsWithOurWriters) {
  nn::Linear model(2, 3);
  nn::Adam adam(model.named_parameters(), nn::AdamOptions{});
  nn::save_checkpoint(corpus("safetensors", "w_linear_checkpoint.safetensors"), model, nullptr,
                      nn::CheckpointInfo{"sky_autoencoder", 7, R"({"a":1})", {}});
  nn::write_safetensors(corpus("safetensors", "w_dtypes.safetensors"),
                        {{"d", Tensor::full({2}, 1.5, DType::F64)},
                         {"i", Tensor::full({1, 2}, 3, DType::I64)},
                         {"s", Tensor::full({}, 2.0)},
                         {"e", Tensor::zeros({0, 3})}},
                        {{"format", "pt"}});

  write_glb(make_box({0, 0, 0}, {1, 1, 1}), corpus("gltf", "w_box.glb"));

  const Tensor rgb = Tensor::full({3, 2, 4}, 0.25), grey = Tensor::full({1, 2, 4}, 0.5),
               rgba = Tensor::full({4, 2, 4}, 0.75);
  write_image(corpus("image", "w_rgb8.png"), rgb);
  write_image(corpus("image", "w_rgb16.png"), rgb, {Transfer::Auto, 16});
  write_image(corpus("image", "w_grey.png"), grey);
  write_image(corpus("image", "w_rgba.png"), rgba);
  write_image(corpus("image", "w_rgb.jpg"), rgb);
  write_image(corpus("image", "w_rgb.exr"), rgb);
  write_image(corpus("image", "w_rgb.hdr"), rgb);
  write_depth(corpus("image", "w_depth.exr"), Tensor::full({1, 2, 4}, 12.0));
}

}  // namespace

}  // namespace sl::test
