// Writes the seeds of tests/fuzz/corpus that our own writers produce (valid checkpoints,
// safetensors, GLB and image files). Disabled: run it by hand after a format change,
//   build/tests/fuzz_tests --gtest_also_run_disabled_tests --gtest_filter='FuzzSeeds.*'
// Hand-made edge cases and crash regressions sit beside these files and are not rewritten.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "data/image_io.h"
#include "nn/checkpoint.h"
#include "nn/modules/linear.h"
#include "nn/optim.h"
#include "render/gltf_writer.h"
#include "render/primitives.h"
#include "tests/support/tflite_builder.h"

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

void spit(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// TFLite seeds from the hand-built model of tests/support/tflite_builder.h (there is no writer).
TEST(FuzzSeeds, DISABLED_WriteTfliteSeeds) {
  spit(corpus("tflite", "w_tiny.tflite"), tiny_tflite().bytes);
  {
    // Depthwise, pooling, ADD, FLOAT32 and FLOAT16 constants, a buffer at an absolute file offset.
    TinyTflite t = tiny_tflite();
    const std::vector<float> f = {0.5f, -1.0f};
    std::vector<uint8_t> fb(8);
    std::memcpy(fb.data(), f.data(), 8);
    t.buffers->items[2] = fb_table()->ref(0, fb_vec(fb));
    t.buffers->items.push_back(fb_table()->scalar<uint64_t>(1, 0)->scalar<uint64_t>(2, 4));
    t.tensor[2]->scalars = {{1, std::string(1, '\0')}, {2, std::string("\x02\0\0\0", 4)}};  // FLOAT32 [2]
    t.tensor.push_back(fb_table()->ref(0, fb_vec<int32_t>({2}))->scalar<int8_t>(1, 1)->scalar<uint32_t>(2, 4)
                           ->ref(3, fb_string("half")));
    t.tensors->items = t.tensor;
    t.opcodes->items.push_back(fb_table()->scalar<int8_t>(0, 4));
    t.opcodes->items.push_back(fb_table()->scalar<int8_t>(0, 1));
    t.opcodes->items.push_back(fb_table()->scalar<int8_t>(0, 0));
    t.operators->items.push_back(
        fb_table()->scalar<uint32_t>(0, 3)->ref(1, fb_vec<int32_t>({0, 1, 2}))->ref(2, fb_vec<int32_t>({3}))
            ->scalar<uint8_t>(3, 2)
            ->ref(4, fb_table()->scalar<int8_t>(0, 0)->scalar<int32_t>(1, 1)->scalar<int32_t>(2, 1)
                         ->scalar<int32_t>(3, 1)->scalar<int8_t>(4, 3)->scalar<int32_t>(5, 2)->scalar<int32_t>(6, 2)));
    t.operators->items.push_back(
        fb_table()->scalar<uint32_t>(0, 4)->ref(1, fb_vec<int32_t>({3}))->ref(2, fb_vec<int32_t>({0}))
            ->scalar<uint8_t>(3, 5)
            ->ref(4, fb_table()->scalar<int8_t>(0, 1)->scalar<int32_t>(1, 2)->scalar<int32_t>(2, 2)
                         ->scalar<int32_t>(3, 2)->scalar<int32_t>(4, 2)));
    t.operators->items.push_back(fb_table()->scalar<uint32_t>(0, 5)->ref(1, fb_vec<int32_t>({0, 4}))
                                     ->ref(2, fb_vec<int32_t>({3}))->scalar<uint8_t>(3, 11)
                                     ->ref(4, fb_table()->scalar<int8_t>(0, 1)));
    std::string bytes = FbWriter().build(t.model);
    const uint64_t offset = bytes.size();
    std::memcpy(&bytes[t.buffers->items[4]->pos + 8], &offset, 8);
    spit(corpus("tflite", "w_ops.tflite"), bytes + std::string("\x00\x3c\x00\xc0", 4));
  }
  spit(corpus("tflite", "h_wrong_identifier.tflite"), tiny_tflite("TFL2").bytes);
  spit(corpus("tflite", "h_truncated.tflite"), tiny_tflite().bytes.substr(0, 300));
  {
    TinyTflite t = tiny_tflite();
    std::string bytes = t.bytes;
    const uint32_t huge = 0x80000000u;
    std::memcpy(&bytes[t.tensors->pos], &huge, 4);
    spit(corpus("tflite", "h_vector_2g.tflite"), bytes);
  }
  {
    TinyTflite t = tiny_tflite();
    t.tensors->items.assign(100, t.tensor[1]);
    t.operators->items.resize(1);
    spit(corpus("tflite", "h_shared_tensor.tflite"), FbWriter().build(t.model));
  }
}

}  // namespace

}  // namespace sl::test
