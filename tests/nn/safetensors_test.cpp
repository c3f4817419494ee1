// safetensors reading and writing, official sample files, and hostile inputs; checkpoints.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "autodiff/ops.h"
#include "nn/checkpoint.h"
#include "nn/modules/linear.h"
#include "nn/modules/mlp.h"
#include "nn/safetensors.h"

namespace sl::test {
using nn::Adam;
using nn::CheckpointInfo;
using nn::Linear;
using nn::MLP;
using nn::SafetensorsFile;
using nn::StateDict;
using nn::load_checkpoint;
using nn::read_checkpoint_info;
using nn::read_safetensors;
using nn::save_checkpoint;
using nn::write_safetensors;

namespace {

namespace fs = std::filesystem;

// One folder per test process, removed when the process exits.
fs::path scratch_dir() {
  struct Scratch {
    fs::path dir = fs::temp_directory_path() / ("streetlight_nn_safetensors_" + std::to_string(::getpid()));
    ~Scratch() {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  };
  static Scratch scratch;
  fs::create_directories(scratch.dir);
  return scratch.dir;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void spit(const fs::path& p, const std::string& bytes) {
  // Removing first avoids ext4's flush-on-truncate (auto_da_alloc), which makes rewrites slow.
  fs::remove(p);
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// A file made of an 8-byte length, the given header text and `data_bytes` zero bytes.
std::string make_file(const std::string& header, size_t data_bytes, uint64_t declared = UINT64_MAX) {
  const uint64_t n = declared == UINT64_MAX ? header.size() : declared;
  std::string s(8, '\0');
  std::memcpy(s.data(), &n, 8);
  return s + header + std::string(data_bytes, '\0');
}

// Expects read_safetensors to throw sl::Error whose message names the file and contains `what`.
void expect_rejected(const fs::path& p, const std::string& what) {
  try {
    read_safetensors(p.string());
    ADD_FAILURE() << "no error for " << p << " (expected '" << what << "')";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(p.string()), std::string::npos) << msg;
    EXPECT_NE(msg.find(what), std::string::npos) << msg;
  }
}

TEST(Safetensors, RoundTripKeepsNamesDtypesShapesValuesAndMetadata) {
  const fs::path p = scratch_dir() / "round.safetensors";
  StateDict t;
  t["a.weight"] = Tensor::uniform({3, 4}, -1, 1, 1);
  t["a.bias"] = Tensor::uniform({4}, -1, 1, 2, DType::F64);
  t["count"] = Tensor::from_indices({-5, 7}, {2});
  t["scalar"] = Tensor::scalar(3.5);
  t["empty"] = Tensor::zeros({0, 3});
  t["view"] = transpose(Tensor::uniform({2, 3}, -1, 1, 3), 0, 1);  // non-contiguous
  write_safetensors(p.string(), t, {{"config", "{\"x\": 1}"}, {"stage", "sky"}});
  const SafetensorsFile f = read_safetensors(p.string());
  ASSERT_EQ(f.tensors.size(), t.size());
  for (const auto& [name, want] : t) {
    const Tensor& got = f.tensors.at(name);
    EXPECT_EQ(got.dtype(), want.dtype()) << name;
    EXPECT_EQ(got.shape(), want.shape()) << name;
    EXPECT_EQ(got.to_vector(), want.to_vector()) << name;
  }
  EXPECT_EQ(f.metadata.at("config"), "{\"x\": 1}");
  EXPECT_EQ(f.metadata.at("stage"), "sky");
  EXPECT_EQ(f.file_dtypes.at("count"), "I64");
  uint64_t n = 0;
  const std::string bytes = slurp(p);
  std::memcpy(&n, bytes.data(), 8);
  EXPECT_EQ(n % 8, 0u) << "data should start 8-byte aligned";
}

TEST(Safetensors, AtomicWriteLeavesNoTemporaryAndReplacesTheOldFile) {
  const fs::path dir = scratch_dir() / "atomic";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path p = dir / "ckpt.safetensors";
  write_safetensors(p.string(), {{"x", Tensor::ones({2})}});
  write_safetensors(p.string(), {{"x", Tensor::full({2}, 2.0)}});
  EXPECT_EQ(read_safetensors(p.string()).tensors.at("x").to_vector(), (std::vector<double>{2.0, 2.0}));
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file() ? 1 : 0;
  EXPECT_EQ(files, 1);
  EXPECT_THROW(write_safetensors((dir / "missing_folder" / "x.safetensors").string(), {{"x", Tensor::ones({1})}}),
               Error);
}

fs::path shared_safetensors() {
  return fs::path(STREETLIGHT_SHARED_DATA) / "safetensors";
}

TEST(Safetensors, ReadsEveryOfficialSampleFileInItsDtype) {
  const fs::path dir = shared_safetensors();
  if (!fs::exists(dir / "overall.safetensors"))
    GTEST_SKIP() << "shared data not found at " << dir << " (set STREETLIGHT_SHARED_DATA); skipping";
  const std::vector<double> signed_values = {-3, -2, -1, 0, 1, 2};
  const std::map<std::string, std::pair<std::string, std::vector<double>>> expected = {
      {"f", {"F32", signed_values}},       {"d", {"F64", signed_values}},
      {"e", {"F16", signed_values}},       {"b", {"I8", signed_values}},
      {"B", {"U8", {253, 254, 255, 0, 1, 2}}}, {"h", {"I16", signed_values}},
      {"H", {"U16", {65533, 65534, 65535, 0, 1, 2}}}, {"i", {"I32", signed_values}},
      {"I", {"U32", {4294967293.0, 4294967294.0, 4294967295.0, 0, 1, 2}}}};
  const SafetensorsFile overall = read_safetensors((dir / "overall.safetensors").string());
  EXPECT_EQ(overall.tensors.size(), expected.size());
  for (const auto& [name, want] : expected) {
    // Upper-case names would collide with lower-case ones on case-insensitive file systems;
    // the sample files are distinct here.
    const SafetensorsFile single = read_safetensors((dir / (name + ".safetensors")).string());
    for (const SafetensorsFile* f : {&single, &overall}) {
      ASSERT_TRUE(f->tensors.count(name)) << name;
      EXPECT_EQ(f->file_dtypes.at(name), want.first) << name;
      EXPECT_EQ(f->tensors.at(name).shape(), (Shape{6})) << name;
      EXPECT_EQ(f->tensors.at(name).to_vector(), want.second) << name;
    }
    EXPECT_EQ(single.metadata.at("test"), "a") << name;
  }
  EXPECT_EQ(overall.tensors.at("f").dtype(), DType::F32);
  EXPECT_EQ(overall.tensors.at("d").dtype(), DType::F64);
}

TEST(Safetensors, EveryTruncationOfAValidFileIsAClearError) {
  const fs::path dir = scratch_dir();
  const fs::path src = dir / "whole.safetensors";
  write_safetensors(src.string(), {{"a", Tensor::uniform({5}, -1, 1, 1)}, {"b", Tensor::ones({2, 2}, DType::F64)}},
                    {{"stage", "x"}});
  std::vector<std::string> sources = {slurp(src)};
  if (fs::exists(shared_safetensors() / "overall.safetensors"))
    sources.push_back(slurp(shared_safetensors() / "overall.safetensors"));
  const fs::path cut = dir / "cut.safetensors";
  for (const std::string& whole : sources)
    for (size_t len = 0; len < whole.size(); ++len) {
      spit(cut, whole.substr(0, len));
      EXPECT_THROW(read_safetensors(cut.string()), Error) << "cut at " << len << " of " << whole.size();
    }
}

TEST(Safetensors, HostileHeadersAreRejectedWithoutLargeAllocations) {
  const fs::path p = scratch_dir() / "bad.safetensors";
  spit(p, "");
  expect_rejected(p, "shorter than the 8-byte header length");
  spit(p, make_file("{}", 0, uint64_t(1) << 62));
  expect_rejected(p, "above the 100 MB limit");
  spit(p, make_file("{}", 0, 5000));
  expect_rejected(p, "only 2 bytes follow");
  spit(p, make_file("{\"a\": {\"dtype\": \"F32\"", 0));
  expect_rejected(p, "not valid JSON");
  spit(p, make_file("[1, 2]", 0));
  expect_rejected(p, "must be a JSON object");
  spit(p, make_file(std::string(10000, '[') + std::string(10000, ']'), 0));
  expect_rejected(p, "nests deeper");
  spit(p, make_file("{\"a\": {\"dtype\": \"F32\", \"shape\": [2]}}", 8));
  expect_rejected(p, "has no \"data_offsets\"");
  spit(p, make_file("{\"a\": {\"dtype\": \"F8_E4M3\", \"shape\": [2], \"data_offsets\": [0, 2]}}", 2));
  expect_rejected(p, "tensor 'a' has dtype F8_E4M3");
  spit(p, make_file("{\"a\": {\"dtype\": \"F32\", \"shape\": [-2], \"data_offsets\": [0, 8]}}", 8));
  expect_rejected(p, "non-negative integer");
  spit(p, make_file("{\"a\": {\"dtype\": \"F32\", \"shape\": [3], \"data_offsets\": [0, 8]}}", 8));
  expect_rejected(p, "span 8 bytes but F32[3] needs 12");
  spit(p, make_file("{\"a\": {\"dtype\": \"F64\", \"shape\": [4611686018427387904, 4611686018427387904], "
                    "\"data_offsets\": [0, 8]}}", 8));
  expect_rejected(p, "more than 2^62");
  spit(p, make_file("{\"a\": {\"dtype\": \"F32\", \"shape\": [2], \"data_offsets\": [8, 0]}}", 8));
  expect_rejected(p, "reversed");
  spit(p, make_file("{\"a\": {\"dtype\": \"F32\", \"shape\": [4], \"data_offsets\": [0, 16]}}", 8));
  expect_rejected(p, "beyond the 8 data bytes");
  spit(p, make_file("{\"a\": {\"dtype\": \"F32\", \"shape\": [2], \"data_offsets\": [0, 8]},"
                    " \"b\": {\"dtype\": \"F32\", \"shape\": [2], \"data_offsets\": [4, 12]}}", 16));
  expect_rejected(p, "'a' and 'b' overlap");
  spit(p, make_file("{\"a\": {\"dtype\": \"F32\", \"shape\": [4], \"data_offsets\": [0, 16]},"
                    " \"z\": {\"dtype\": \"F32\", \"shape\": [0], \"data_offsets\": [4, 4]},"
                    " \"b\": {\"dtype\": \"F32\", \"shape\": [1], \"data_offsets\": [8, 12]}}", 16));
  expect_rejected(p, "'a' and 'b' overlap");
  spit(p, make_file("{\"__metadata__\": {\"k\": 3}}", 0));
  expect_rejected(p, "__metadata__ value of 'k' must be a string");
  expect_rejected(scratch_dir() / "does_not_exist.safetensors", "cannot open");
}

TEST(Safetensors, WriterRejectsReservedAndEmptyNames) {
  const fs::path p = scratch_dir() / "names.safetensors";
  EXPECT_THROW(write_safetensors(p.string(), {{"__metadata__", Tensor::ones({1})}}), Error);
  EXPECT_THROW(write_safetensors(p.string(), {{"", Tensor::ones({1})}}), Error);
}

// ---------------------------------------------------------------- checkpoints
TEST(Checkpoint, RoundTripRestoresModelOptimiserStepStageAndConfig) {
  const fs::path p = scratch_dir() / "ckpt.safetensors";
  MLP a({.widths = {2, 8, 1}, .seed = 1});
  Adam oa(a.named_parameters(), {.lr = 0.01});
  const Tensor x = Tensor::uniform({16, 2}, -1, 1, 3);
  for (int i = 0; i < 3; ++i) {
    oa.zero_grad();
    backward(mean(square(a.forward(x))));
    oa.step();
  }
  save_checkpoint(p.string(), a, &oa, {.stage = "sky_autoencoder", .step = 3, .config_json = "{\"lr\": 0.01}",
                                       .extra = {{"note", "hello"}}});
  const SafetensorsFile raw = read_safetensors(p.string());
  EXPECT_TRUE(raw.tensors.count("net.0.weight"));
  EXPECT_TRUE(raw.tensors.count("optim.exp_avg.net.0.weight"));
  EXPECT_TRUE(raw.tensors.count("optim.step.net.2.bias"));
  EXPECT_EQ(raw.metadata.at("format"), "pt");

  MLP b({.widths = {2, 8, 1}, .seed = 99});
  Adam ob(b.named_parameters(), {.lr = 0.01});
  const CheckpointInfo info = load_checkpoint(p.string(), b, &ob);
  EXPECT_EQ(info.stage, "sky_autoencoder");
  EXPECT_EQ(info.step, 3);
  EXPECT_EQ(info.config_json, "{\"lr\": 0.01}");
  EXPECT_EQ(info.extra.at("note"), "hello");
  EXPECT_EQ(read_checkpoint_info(p.string()).step, 3);
  // Continuing both runs gives identical parameters.
  for (auto* run : {&a, &b}) {
    Adam& o = run == &a ? oa : ob;
    o.zero_grad();
    backward(mean(square(run->forward(x))));
    o.step();
  }
  const auto pa = a.named_parameters(), pb = b.named_parameters();
  for (size_t i = 0; i < pa.size(); ++i) EXPECT_EQ(pa[i].second.to_vector(), pb[i].second.to_vector()) << pa[i].first;

  MLP c({.widths = {2, 8, 1}, .seed = 5});  // model-only load ignores the optimiser entries
  load_checkpoint(p.string(), c, nullptr);
  EXPECT_EQ(c.named_parameters()[0].second.to_vector(), raw.tensors.at("net.0.weight").to_vector());
}

TEST(Checkpoint, MismatchedModelGetsOneMessageAndStaysUntouched) {
  const fs::path p = scratch_dir() / "ckpt_mismatch.safetensors";
  MLP a({.widths = {2, 8, 1}, .seed = 1});
  save_checkpoint(p.string(), a, nullptr, {.stage = "s", .step = 1});
  MLP b({.widths = {2, 4, 1, 1}, .seed = 2});
  const std::vector<double> before = b.named_parameters()[0].second.to_vector();
  Adam ob(b.named_parameters(), {});
  try {
    load_checkpoint(p.string(), b, &ob);
    FAIL();
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(p.string()), std::string::npos) << m;
    EXPECT_NE(m.find("missing: "), std::string::npos) << m;
    EXPECT_NE(m.find("net.4.weight"), std::string::npos) << m;
    EXPECT_NE(m.find("optim.exp_avg.net.0.weight"), std::string::npos) << m;
    EXPECT_NE(m.find("net.0.weight: expected f32[4, 2], got f32[8, 2]"), std::string::npos) << m;
  }
  EXPECT_EQ(b.named_parameters()[0].second.to_vector(), before);
}

TEST(Checkpoint, ReservedExtraKeysAndBadStepAreRejected) {
  const fs::path p = scratch_dir() / "ckpt_keys.safetensors";
  Linear l(1, 1);
  EXPECT_THROW(save_checkpoint(p.string(), l, nullptr, {.extra = {{"step", "1"}}}), Error);
  write_safetensors(p.string(), l.state_dict(), {{"step", "12x"}});
  EXPECT_THROW(load_checkpoint(p.string(), l, nullptr), Error);
}

}  // namespace
}  // namespace sl::test
