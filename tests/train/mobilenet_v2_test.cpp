// nn::MobileNetV2 and its ImageNet weights (nn/modules/mobilenet_v2_tflite.h). The ImageNet check
// sits with the train tests because it decodes JPEG photos (data/image_io.h), which nn may not use.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "autodiff/ops.h"
#include "data/image_io.h"
#include "nn/modules/mobilenet_v2.h"
#include "nn/modules/mobilenet_v2_tflite.h"
#include "support/test_files.h"

namespace sl::test {
namespace {

namespace fs = std::filesystem;

const char* kWeights = "weights/mobilenet_v2_1.0_224_quant.tflite";

TEST(MobileNetV2, SamePaddingIsTensorFlows) {
  // stride 2 on an even extent: the one padded row goes after; on an odd extent one each side.
  EXPECT_EQ(nn::same_padding(224, 3, 2), std::make_pair(int64_t{0}, int64_t{1}));
  EXPECT_EQ(nn::same_padding(7, 3, 2), std::make_pair(int64_t{1}, int64_t{1}));
  EXPECT_EQ(nn::same_padding(16, 3, 1), std::make_pair(int64_t{1}, int64_t{1}));
  EXPECT_EQ(nn::same_padding(1, 3, 2), std::make_pair(int64_t{1}, int64_t{1}));
}

TEST(MobileNetV2, MapsAndPoolsAtStride32AndPassesGradientsToTheStem) {
  nn::MobileNetV2 net({.num_classes = 0, .seed = 3});
  EXPECT_EQ(net.blocks().size(), 17u);
  const Tensor x = Tensor::uniform({2, 3, 64, 96}, -1.0, 1.0, 7);
  const Tensor map = net.forward_map(x);
  EXPECT_EQ(map.shape(), (Shape{2, nn::MobileNetV2::kFeatures, 2, 3}));
  const Tensor odd = net.forward_map(Tensor::uniform({1, 3, 33, 47}, -1.0, 1.0, 8));
  EXPECT_EQ(odd.shape(), (Shape{1, nn::MobileNetV2::kFeatures, 2, 2}));  // ceil(33/32), ceil(47/32)
  Tensor loss = sum(net.forward(x));
  backward(loss);
  const std::vector<double> g = net.stem().parameter("weight").grad().to_vector();
  double norm = 0.0;
  for (double v : g) {
    ASSERT_TRUE(std::isfinite(v));
    norm += v * v;
  }
  EXPECT_GT(norm, 0.0);
  EXPECT_THROW(net.forward(Tensor::zeros({1, 4, 32, 32})), Error);
}

// The ImageNet weights classify ImageNet photos: the 100 samples (every tenth class; sorted by
// WordNet id, sample k is class 10k, the model's output 10k + 1, as 0 is "background").
TEST(MobileNetV2, TheImageNetWeightsClassifyImageNetPhotos) {
  const std::string weights = shared_data(kWeights), folder = shared_data("weights/imagenet_samples_224");
  if (!fs::is_regular_file(weights) || !fs::is_directory(folder))
    GTEST_SKIP() << "needs ../shared/data/" << kWeights << " and weights/imagenet_samples_224 (not in a fresh clone)";
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(folder))
    if (e.path().extension() == ".jpg") files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  ASSERT_EQ(files.size(), 100u);

  nn::MobileNetV2 net({.num_classes = 1001});
  load_mobilenet_v2_tflite(net, weights);
  net.eval();
  const NoGradGuard no_grad;
  int top1 = 0, top5 = 0;
  for (size_t first = 0; first < files.size(); first += 10) {
    TensorList images;
    for (size_t k = first; k < first + 10; ++k)
      images.push_back(data::read_image(files[k], {.transfer = data::Transfer::Linear, .channels = 3,
                                                   .width = 224, .height = 224}));
    const std::vector<double> logits = net.forward(nn::imagenet_input(stack(images, 0))).to_vector();
    for (size_t i = 0; i < 10; ++i) {
      const int64_t truth = static_cast<int64_t>(10 * (first + i) + 1);
      const double* row = logits.data() + i * 1001;
      ASSERT_TRUE(std::all_of(row, row + 1001, [](double v) { return std::isfinite(v); }));
      int64_t above = 0;  // classes scored above the true one
      for (int64_t c = 0; c < 1001; ++c) above += row[c] > row[truth];
      top1 += above == 0;
      top5 += above < 5;
    }
  }
  // Published: 70.8% top-1, 89.9% top-5 on ImageNet validation (the 8-bit model); these 100 samples
  // give 84 and 99 (2026-11-30): a wrong padding or layout falls far below.
  EXPECT_GE(top1, 75) << "top-5 " << top5;
  EXPECT_GE(top5, 92) << "top-1 " << top1;
  RecordProperty("top1", top1);
  RecordProperty("top5", top5);
}

TEST(MobileNetV2, TheLoaderRefusesAModelThatDoesNotFitAndWritesNothing) {
  const std::string weights = shared_data(kWeights);
  if (!fs::is_regular_file(weights)) GTEST_SKIP() << "needs ../shared/data/" << kWeights << " (not in a fresh clone)";
  nn::MobileNetV2 net({.num_classes = 10});
  const std::vector<double> before = net.stem().parameter("weight").to_vector();
  try {
    load_mobilenet_v2_tflite(net, weights);
    ADD_FAILURE() << "loaded 1001 classes into a 10-class classifier";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(weights), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("classifier"), std::string::npos) << e.what();
  }
  EXPECT_EQ(net.stem().parameter("weight").to_vector(), before);
  // Without a classifier the file's last convolution is left out.
  nn::MobileNetV2 features({.num_classes = 0});
  EXPECT_NO_THROW(load_mobilenet_v2_tflite(features, weights));
  EXPECT_THROW(load_mobilenet_v2_tflite(features, shared_data("weights/imagenet_labels.txt")), Error);
}

}  // namespace
}  // namespace sl::test
