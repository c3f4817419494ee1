// streetlight-export: the released-weights form keeps predictor.* only, or with
// --with-discriminator also the stage-3 discriminator that streetlight-insert --refine needs;
// --blend interpolates two checkpoints of one model.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "autodiff/ops.h"
#include "nn/safetensors.h"
#include "support/tool_fixture.h"
#include "train/lighting_refinement.h"

namespace sl::test {

namespace fs = std::filesystem;

namespace {

size_t count_prefix(const std::string& path, const std::string& prefix) {
  const nn::SafetensorsFile f = nn::read_safetensors(path);
  return static_cast<size_t>(std::count_if(f.tensors.begin(), f.tensors.end(),
                                           [&](const auto& kv) { return kv.first.rfind(prefix, 0) == 0; }));
}

TEST(ExportTool, KeepsTheDiscriminatorOnlyWhenAsked) {
  if (!tool_built("streetlight-export")) GTEST_SKIP() << "streetlight-export not built";
  const std::string dir = tool_dir("export_discriminator");
  const std::string adv = tiny_adversarial_checkpoint(dir);
  const auto plain = run_tool("streetlight-export", "--checkpoint " + adv + " --out " + dir + "/plain.safetensors");
  ASSERT_EQ(plain.code, 0) << plain.out;
  EXPECT_GT(count_prefix(dir + "/plain.safetensors", "predictor."), 0u);
  EXPECT_EQ(count_prefix(dir + "/plain.safetensors", "discriminator."), 0u);
  EXPECT_FALSE(train::load_discriminator(dir + "/plain.safetensors"));

  const auto with_d = run_tool("streetlight-export", "--checkpoint " + adv + " --with-discriminator --out " + dir +
                                                         "/with_d.safetensors");
  ASSERT_EQ(with_d.code, 0) << with_d.out;
  EXPECT_EQ(count_prefix(dir + "/with_d.safetensors", "discriminator."), count_prefix(adv, "discriminator."));
  // F16 weights: the exported D scores like the checkpoint's to F16 precision.
  const auto d_ckpt = train::load_discriminator(adv), d_export = train::load_discriminator(dir + "/with_d.safetensors");
  ASSERT_TRUE(d_ckpt && d_export);
  const Tensor x = Tensor::uniform({1, 3, 32, 64}, 0.0, 1.0, 3);
  const Tensor a = d_ckpt->forward(x), b = d_export->forward(x);
  EXPECT_LT(max(abs(sub(a, b))).item(), 1e-2 * std::max(1.0, max(abs(a)).item()));

  // streetlight-insert --refine finds it in the export.
  tiny_photo(dir);
  const auto ins = run_tool("streetlight-insert", "--checkpoint " + dir + "/with_d.safetensors --refine 1 --image " + dir +
                                                      "/photo.png --intrinsics " + dir + "/intrinsics.json --at 0,8"
                                                      " --object procedural:car --aa 1 --light-samples 4 --shadow-rays 8"
                                                      " --shadow-width 16 --shadow-height 8 --out " + dir + "/out");
  EXPECT_EQ(ins.code, 0) << ins.out;
}

TEST(ExportTool, WithDiscriminatorOnAStageWithoutOneIsACleanError) {
  if (!tool_built("streetlight-export")) GTEST_SKIP();
  const std::string dir = tool_dir("export_no_discriminator");
  const std::string lighting = tiny_lighting_checkpoint(dir);
  const std::string out = dir + "/out.safetensors";
  const auto r = run_tool("streetlight-export", "--checkpoint " + lighting + " --with-discriminator --out " + out);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_EQ(r.out.rfind("error: ", 0), 0u) << r.out;
  EXPECT_NE(r.out.find(lighting), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(out));
}

// A copy of `path` with every float predictor tensor shifted by `shift` (drop: that tensor left out).
std::string shifted_copy(const std::string& path, const std::string& out, double shift, const std::string& drop = "") {
  nn::SafetensorsFile f = nn::read_safetensors(path);
  nn::StateDict tensors;
  for (const auto& [name, t] : f.tensors) {
    if (name == drop) continue;
    tensors.emplace(name, name.rfind("predictor.", 0) == 0 && t.dtype() == DType::F32 ? add(t, Tensor::scalar(shift)) : t);
  }
  nn::write_safetensors(out, tensors, f.metadata);
  return out;
}

TEST(ExportTool, BlendWritesTheInterpolationOfTwoCheckpointsTensorByTensor) {
  if (!tool_built("streetlight-export")) GTEST_SKIP();
  const std::string dir = tool_dir("export_blend");
  const std::string a = tiny_lighting_checkpoint(dir), b = shifted_copy(a, dir + "/b.safetensors", 0.5);
  const std::string out = dir + "/blend.safetensors";
  const auto r = run_tool("streetlight-export", "--checkpoint " + a + " --blend " + b + " --blend-t 0.25 --f32 --out " + out);
  ASSERT_EQ(r.code, 0) << r.out;
  const nn::SafetensorsFile fa = nn::read_safetensors(a), fb = nn::read_safetensors(b), fo = nn::read_safetensors(out);
  EXPECT_EQ(fo.metadata.at("blend_t"), "0.25");
  EXPECT_EQ(fo.metadata.at("blended_with"), "b.safetensors");
  size_t checked = 0;
  for (const auto& [name, t] : fo.tensors) {
    if (t.dtype() != DType::F32) continue;
    const std::vector<double> o = t.to_vector(), va = fa.tensors.at(name).to_vector(), vb = fb.tensors.at(name).to_vector();
    for (size_t i = 0; i < o.size(); ++i) {
      const double want = 0.75 * va[i] + 0.25 * vb[i];
      ASSERT_NEAR(o[i], want, 1e-6 * (1.0 + std::abs(want))) << name << "[" << i << "]";
    }
    ++checked;
  }
  EXPECT_GT(checked, 10u);

  // Bad input: one line, exit 2, no file.
  const std::string bad_out = dir + "/bad.safetensors";
  const std::string some_tensor = fa.tensors.rbegin()->first;
  const std::string missing = shifted_copy(a, dir + "/missing.safetensors", 0.0, some_tensor);
  for (const auto& [args, named] : std::vector<std::pair<std::string, std::string>>{
           {"--blend " + b + " --blend-t 1.5", "--blend-t"},
           {"--blend " + b + " --blend-t nan", "--blend-t"},
           {"--blend-t 0.5", "--blend-t"},
           {"--blend " + missing, some_tensor}}) {
    const auto e = run_tool("streetlight-export", "--checkpoint " + a + " " + args + " --out " + bad_out);
    EXPECT_EQ(e.code, 2) << args << ": " << e.out;
    EXPECT_EQ(std::count(e.out.begin(), e.out.end(), '\n'), 1) << e.out;
    EXPECT_NE(e.out.find(named), std::string::npos) << e.out;
    EXPECT_FALSE(fs::exists(bad_out)) << args;
  }
}

}  // namespace

}  // namespace sl::test
