// Data-parallel training under mpirun (issue 18, docs/DISTRIBUTED.md). Built and registered only
// when CMake found MPI. Each test runs streetlight-train under `mpirun -np 2` on tiny configs and
// compares with one process: the sky stage's loss curve equals one process at twice the batch;
// the lighting stage's follows it within the tolerance that per-rank BatchNorm statistics (the
// ResNet backbone) allow, and a step with a frozen model shows that the statistics ARE per rank;
// stage 3 keeps the replicas (discriminator included) bit-identical; killing a rank stops the job
// and leaves the last checkpoint loadable.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "nn/checkpoint.h"
#include "nn/safetensors.h"

namespace sl::test {

namespace {

namespace fs = std::filesystem;
using Curve = std::vector<nlohmann::json>;

const fs::path kTrain = fs::path(STREETLIGHT_BINARY_DIR) / "tools" / "streetlight-train";
const fs::path kDatagen = fs::path(STREETLIGHT_BINARY_DIR) / "tools" / "streetlight-datagen";
const fs::path kConfigs = fs::path(STREETLIGHT_SOURCE_DIR) / "configs";

// One folder per test process (ctest runs the tests in parallel processes).
fs::path scratch() {
  const fs::path d = fs::path(STREETLIGHT_BINARY_DIR) / "test_tmp" / "distributed" /
                     (std::to_string(::getpid()) + "_" +
                      ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// mpirun as root needs the first two; the ranks share 2 cores with other tests, so they yield
// the core while they wait in a collective instead of spinning on it.
std::string mpirun(int ranks) {
  ::setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
  ::setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
  ::setenv("OMPI_MCA_mpi_yield_when_idle", "1", 1);
  return std::string(STREETLIGHT_MPIEXEC) + " -np " + std::to_string(ranks) + " --oversubscribe --bind-to none ";
}

std::string read_text(const fs::path& p) {
  std::stringstream ss;
  ss << std::ifstream(p).rdbuf();
  return ss.str();
}

int run(const std::string& cmd, const fs::path& err) {
  const int status = std::system((cmd + " > /dev/null 2> " + err.string()).c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

Curve train_curve(const fs::path& out) {
  Curve c;
  std::ifstream f(out / "metrics.jsonl");
  for (std::string line; std::getline(f, line);) {
    nlohmann::json j = nlohmann::json::parse(line);
    if (j.at("split") == "train") c.push_back(j);
  }
  return c;
}

double rel(double a, double b) { return std::abs(a - b) / std::max(std::abs(a), 1e-12); }

// Tolerances from the arithmetic, not from one CPU (issue 38). u = 2^-24 is float32's unit
// roundoff. One process at batch 4 and two ranks at batch 2 add the same float32 terms in other
// orders: the batch is summed in one GEMM or as 2 + 2 averaged across ranks, and a GEMM's blocking
// follows the batch size and the cache sizes the CPU reports, so the order differs between CPUs
// too. A sum of n terms taken in another order moves by about sqrt(n)·u relative (the roundings
// of a long sum add like a random walk; blocked sums stay far below the worst case (n − 1)·u).
// The largest sum of the sky stage's loss is its HDR term over batch × 3 × 16 × 64 texels of the
// quickstart dome. Each step's update carries the earlier steps' differences forward; Adam
// normalises its steps, so a relative perturbation of the gradient is not amplified by the
// update, and over `steps` steps the differences add at most linearly:
//   bound = steps · sqrt(n) · u   (20 steps, n = 12,288: 1.3e-4).
// Measured worst differences: 8.3e-7 on an Intel Xeon (family 6, model 167), 4.8e-5 on an Intel
// Xeon of the Cooper Lake class, below 1e-5 on an AMD EPYC (Zen 4). A run that sees only half of
// each batch (a sharding bug) differs by far more; the sky test checks that the bound still
// separates the two.
constexpr double kFloatRoundoff = 0x1p-24;
constexpr int64_t kSkyLossTerms = 4 * 3 * 16 * 64;  // quickstart_sky.json's dome, global batch 4
double reordered_sum_bound(int steps, int64_t terms) {
  return steps * std::sqrt(static_cast<double>(terms)) * kFloatRoundoff;
}

double worst_rel(const Curve& a, const Curve& b) {
  double worst = 0;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i)
    worst = std::max(worst, rel(a[i]["loss"].get<double>(), b[i]["loss"].get<double>()));
  return worst;
}

// Trains `config` with `sets` on one process (batch b1) or under mpirun (ranks, batch per rank).
Curve train(const fs::path& dir, const std::string& name, const std::string& config, const std::string& sets,
            int ranks, int batch) {
  const fs::path out = dir / name;
  const std::string cmd = (ranks > 1 ? mpirun(ranks) : std::string()) + kTrain.string() + " --config " + config +
                          " " + sets + " --set train.batch_size=" + std::to_string(batch) + " --out " + out.string();
  const int code = run(cmd, dir / (name + ".err"));
  EXPECT_EQ(code, 0) << cmd << "\n" << read_text(dir / (name + ".err"));
  return train_curve(out);
}

// The quickstart sky stage for 20 steps; with the shared HDRIs when `hdri` (as the quickstart),
// else sky-model skies only (faster: every rank reads the HDRIs at start).
std::string sky_sets(bool hdri_mix = false) {
  const fs::path hdri = hdri_mix ? fs::path(STREETLIGHT_SHARED_DATA) / "hdri" : fs::path("/nonexistent");
  return "--set train.steps=20 --set train.log_every=1 --set train.val_every=20 --set train.checkpoint_every=10 "
         "--set train.image_every=1000 --set data.val_size=2 --set data.hdri_dir=" +
         (fs::exists(hdri) ? hdri.string() : std::string());
}

// A tiny generated street dataset and a stage-1 checkpoint of the quickstart sky model.
struct LightingFixture {
  fs::path dir;
  std::string sets;
  bool ok = false;
};

LightingFixture lighting_fixture() {
  LightingFixture f;
  f.dir = scratch();
  std::ofstream(f.dir / "datagen.json") << R"({"seed": 7, "samples": 6,
    "render": {"spp": 2, "max_depth": 2, "environment_width": 64, "target_noise": 0},
    "panorama": {"width": 32, "height": 16}, "views": {"width": 48, "height": 24},
    "sky": {"width": 64, "height": 16}, "insertion": {"min_visible_pixels": 4, "coverage_samples": 2},
    "splits": {"train": 0.67, "val": 0.17}})";
  const fs::path street = f.dir / "street";
  if (run(kDatagen.string() + " --config " + (f.dir / "datagen.json").string() + " --out " + street.string(),
          f.dir / "datagen.err") != 0) {
    ADD_FAILURE() << read_text(f.dir / "datagen.err");
    return f;
  }
  const fs::path sky = f.dir / "sky";
  if (run(kTrain.string() + " --config " + (kConfigs / "quickstart_sky.json").string() +
              " --set train.steps=2 --set train.val_every=2 --set train.checkpoint_every=2 --set train.image_every=100"
              " --set data.hdri_dir= --set data.val_size=1 --out " + sky.string(),
          f.dir / "sky.err") != 0) {
    ADD_FAILURE() << read_text(f.dir / "sky.err");
    return f;
  }
  f.sets = "--set init.sky_checkpoint=" + (sky / "last.safetensors").string() + " --set data.dataset=" +
           street.string() +
           " --set train.log_every=1 --set train.image_every=1000 --set data.val_size=1";
  f.ok = true;
  return f;
}

TEST(DataParallel, SkyStageTwoRanksMatchOneProcessAtTwiceTheBatch) {
  const fs::path dir = scratch();
  const std::string cfg = (kConfigs / "quickstart_sky.json").string();
  const Curve one = train(dir, "one", cfg, sky_sets(true), 1, 4);
  const Curve two = train(dir, "two", cfg, sky_sets(true), 2, 2);
  // Rank 0 alone logs: one line per step, not two.
  ASSERT_EQ(one.size(), 20u);
  ASSERT_EQ(two.size(), 20u);
  for (size_t i = 0; i < one.size(); ++i) {
    EXPECT_EQ(one[i]["step"], two[i]["step"]);
    EXPECT_TRUE(two[i].contains("time_allreduce_ms"));
  }
  const double bound = reordered_sum_bound(20, kSkyLossTerms);
  const double worst = worst_rel(one, two);
  EXPECT_LE(worst, bound) << "the sky model has no BatchNorm: the curves must agree to float rounding";
  RecordProperty("worst_relative_difference", std::to_string(worst));
  // The bound still catches a run that trains on half of each batch (what a rank reading the
  // wrong shard would do): that run differs by more than ten times the bound.
  const Curve half = train(dir, "half", cfg, sky_sets(true), 1, 2);
  ASSERT_EQ(half.size(), 20u);
  EXPECT_GT(worst_rel(one, half), 10 * bound);
  RecordProperty("half_batch_worst_relative_difference", std::to_string(worst_rel(one, half)));
  EXPECT_GT(one.front()["loss"].get<double>(), one.back()["loss"].get<double>()) << "the run must learn";
  // The checkpoint records the world it was written by.
  const auto info = sl::nn::read_checkpoint_info((dir / "two" / "last.safetensors").string());
  EXPECT_EQ(info.step, 20);
  EXPECT_EQ(info.extra.at("world_size"), "2");
  EXPECT_EQ(info.extra.at("global_batch"), "4");
}

TEST(DataParallel, GlobalBatchKeySplitsTheBatchOverRanks) {
  const fs::path dir = scratch();
  const std::string cfg = (kConfigs / "quickstart_sky.json").string();
  const std::string sets = sky_sets() + " --set train.steps=5 --set train.global_batch=4";
  const Curve one = train(dir, "one", cfg, sets, 1, 1);  // batch_size is overridden: 4 per step
  const Curve two = train(dir, "two", cfg, sets, 2, 1);  // 2 per rank
  ASSERT_EQ(one.size(), 5u);
  ASSERT_EQ(two.size(), 5u);
  for (size_t i = 0; i < one.size(); ++i)  // the bound of the sky test, over 5 steps
    EXPECT_LE(rel(one[i]["loss"].get<double>(), two[i]["loss"].get<double>()), reordered_sum_bound(5, kSkyLossTerms))
        << "step " << i + 1;
  // A global batch the ranks cannot split is bad input on every rank.
  const int code = run(mpirun(2) + kTrain.string() + " --config " + cfg + " " + sky_sets() +
                           " --set train.global_batch=3 --out " + (dir / "bad").string(),
                       dir / "bad.err");
  EXPECT_EQ(code, 2);
  EXPECT_NE(read_text(dir / "bad.err").find("train.global_batch = 3 is not a multiple of the 2 ranks"),
            std::string::npos)
      << read_text(dir / "bad.err");
}

// Resume (docs/DISTRIBUTED.md): with the same ranks it is bit-identical; with another N and the
// same global batch, each step sees the same samples and random numbers, so the curve agrees to
// float rounding: both continue from the same checkpoint, so the sky test's bound applies over the
// 9 steps after it. The first run stops after 11 steps (warmup 10): its lr schedule up to there is
// that of the 20-step run.
TEST(DataParallel, ResumeIsBitIdenticalWithTheSameRanksAndCloseWithAnother) {
  const fs::path dir = scratch();
  const std::string cfg = (kConfigs / "quickstart_sky.json").string();
  const Curve whole = train(dir, "whole", cfg, sky_sets(), 2, 2);
  train(dir, "first", cfg, sky_sets() + " --set train.steps=11", 2, 2);
  const std::string resume = " --resume " + (dir / "first" / "last.safetensors").string();
  const Curve same = train(dir, "same", cfg, sky_sets() + resume, 2, 2);
  const Curve one = train(dir, "one", cfg, sky_sets() + resume, 1, 4);
  ASSERT_EQ(whole.size(), 20u);
  ASSERT_EQ(same.size(), 9u);
  ASSERT_EQ(one.size(), 9u);
  for (size_t i = 0; i < same.size(); ++i) {
    const nlohmann::json& ref = whole[11 + i];
    ASSERT_EQ(same[i]["step"], ref["step"]);
    EXPECT_EQ(same[i]["loss"].get<double>(), ref["loss"].get<double>()) << "step " << ref["step"];
    EXPECT_LE(rel(one[i]["loss"].get<double>(), ref["loss"].get<double>()), reordered_sum_bound(9, kSkyLossTerms))
        << "step " << ref["step"];
  }
}

// Tolerance (docs/DISTRIBUTED.md): the lighting predictor's ResNet backbone has BatchNorm with
// per-rank statistics, so a rank normalises its one image with that image's statistics where one
// process normalises two images together. The forward differs from step 1 on; over 20 steps the
// measured loss difference is at most 17% (mean 5%). The test bounds it at 30% / 10%. This is not a
// rounding bound: the statistics change the forward itself, by an amount that depends on the
// images, not on the CPU.
TEST(DataParallel, LightingStageFollowsOneProcessWithinTheBatchNormTolerance) {
  const LightingFixture f = lighting_fixture();
  ASSERT_TRUE(f.ok);
  const std::string cfg = (kConfigs / "quickstart_lighting.json").string();
  const std::string sets = f.sets + " --set train.steps=20 --set train.val_every=20 --set train.checkpoint_every=10";
  const Curve one = train(f.dir, "one", cfg, sets, 1, 2);
  const Curve two = train(f.dir, "two", cfg, sets, 2, 1);
  ASSERT_EQ(one.size(), 20u);
  ASSERT_EQ(two.size(), 20u);
  double worst = 0, mean = 0;
  for (size_t i = 0; i < one.size(); ++i) {
    const double r = rel(one[i]["loss"].get<double>(), two[i]["loss"].get<double>());
    worst = std::max(worst, r);
    mean += r / static_cast<double>(one.size());
  }
  EXPECT_LE(worst, 0.30);
  EXPECT_LE(mean, 0.10);
  EXPECT_GT(one.front()["loss"].get<double>(), one.back()["loss"].get<double>());
  EXPECT_GT(two.front()["loss"].get<double>(), two.back()["loss"].get<double>());
}

// Which statistics: with a learning rate too small to move any float32 weight, the 2-rank step's
// per-sample loss terms equal the mean of two one-sample runs (each image normalised alone: per-rank
// statistics) to float rounding, and differ from one process normalising both images together.
TEST(DataParallel, BatchNormUsesPerRankStatistics) {
  const LightingFixture f = lighting_fixture();
  ASSERT_TRUE(f.ok);
  const std::string cfg = (kConfigs / "quickstart_lighting.json").string();
  const std::string sets = f.sets +
                           " --set optim.lr=1e-30 --set optim.min_lr=0 --set train.steps=2 --set train.val_every=2"
                           " --set train.checkpoint_every=2";
  const Curve single = train(f.dir, "single", cfg, sets, 1, 1);  // step 1: sample 0, step 2: sample 1
  const Curve joint = train(f.dir, "joint", cfg, sets, 1, 2);    // step 1: samples 0 and 1 together
  const Curve ranks = train(f.dir, "ranks", cfg, sets, 2, 1);    // step 1: sample 0 on rank 0, 1 on rank 1
  ASSERT_EQ(single.size(), 2u);
  ASSERT_EQ(joint.size(), 2u);
  ASSERT_EQ(ranks.size(), 2u);
  double largest = 0;
  for (const char* k : {"radiance", "depth", "sky_separation", "sky_intensity", "sky_latent"}) {
    const double per_rank = 0.5 * (single[0][k].get<double>() + single[1][k].get<double>());
    // The same one-image forward with the same weights on both sides, averaged in double: equal
    // (measured) or a few roundings of a float32 loss apart, far below the sky test's bound.
    EXPECT_LE(rel(per_rank, ranks[0][k].get<double>()), 16 * kFloatRoundoff) << k;
    const double joint_vs_ranks = rel(joint[0][k].get<double>(), ranks[0][k].get<double>());
    EXPECT_GT(joint_vs_ranks, 16 * kFloatRoundoff) << k;  // more than rounding; measured: 8e-5 .. 1.5e-2
    largest = std::max(largest, joint_vs_ranks);
  }
  EXPECT_GT(largest, 1e-3);
}

// Stage 3: the discriminator trains data-parallel too. Every checkpoint first checks that all
// replicas hold bit-identical parameters (train/gradient_allreduce.h); a divergence fails the run.
TEST(DataParallel, AdversarialStageKeepsEveryReplicaIdentical) {
  const LightingFixture f = lighting_fixture();
  ASSERT_TRUE(f.ok);
  const std::string sets = f.sets + " --set train.steps=2 --set train.val_every=2 --set train.checkpoint_every=2";
  train(f.dir, "lighting", (kConfigs / "quickstart_lighting.json").string(), sets, 1, 2);
  const std::string adv_sets = f.sets + " --set init.checkpoint=" + (f.dir / "lighting" / "last.safetensors").string() +
                               " --set train.steps=4 --set train.val_every=4 --set train.checkpoint_every=1";
  const Curve two = train(f.dir, "adversarial", (kConfigs / "quickstart_adversarial.json").string(), adv_sets, 2, 1);
  ASSERT_EQ(two.size(), 4u);
  for (const auto& line : two) {
    EXPECT_TRUE(line.contains("d_loss")) << line.dump();
    EXPECT_TRUE(std::isfinite(line["d_loss"].get<double>()));
  }
  const sl::nn::SafetensorsFile st = sl::nn::read_safetensors((f.dir / "adversarial" / "last.safetensors").string());
  bool has_discriminator = false;
  for (const auto& [name, t] : st.tensors) has_discriminator |= name.rfind("discriminator.", 0) == 0;
  EXPECT_TRUE(has_discriminator);
}

// Mixed with real-panorama crops (which have no insertion), some steps give one rank an insertable
// sample and the other none (4 of these 8 steps when checked with a print): that rank must still
// take part in both updates. A mismatch of collectives aborts the job (it did, before the fix);
// diverged replicas fail the checkpoint. Steps where no rank can insert skip the discriminator
// and log no d_loss, as in one process.
TEST(DataParallel, AdversarialStageWithARankWithoutInsertableSamples) {
  const fs::path hdri = fs::path(STREETLIGHT_SHARED_DATA) / "hdri";
  if (!fs::exists(hdri)) GTEST_SKIP() << "needs the shared HDRIs (" << hdri << ")";
  const LightingFixture f = lighting_fixture();
  ASSERT_TRUE(f.ok);
  const std::string sets = f.sets + " --set train.steps=2 --set train.val_every=2 --set train.checkpoint_every=2";
  train(f.dir, "lighting", (kConfigs / "quickstart_lighting.json").string(), sets, 1, 2);
  const std::string adv_sets =
      f.sets + " --set init.checkpoint=" + (f.dir / "lighting" / "last.safetensors").string() +
      " --set data.real_fraction=0.5 --set data.hdri_dir=" + hdri.string() + " --set data.hdri_split=" +
      (kConfigs / "hdri_split.json").string() +
      " --set data.real_val_crops=0 --set train.steps=8 --set train.val_every=8 --set train.checkpoint_every=1";
  const Curve two = train(f.dir, "adversarial", (kConfigs / "quickstart_adversarial.json").string(), adv_sets, 2, 1);
  ASSERT_EQ(two.size(), 8u);
  int with_discriminator = 0;
  for (const auto& line : two) {
    if (!line.contains("d_loss")) continue;
    ++with_discriminator;
    EXPECT_TRUE(line["d_loss"].is_number() && std::isfinite(line["d_loss"].get<double>())) << line.dump();
  }
  EXPECT_GE(with_discriminator, 4);
}

// The child processes of `parent` whose environment says OMPI_COMM_WORLD_RANK=rank.
pid_t rank_pid(pid_t parent, int rank) {
  const std::string want = "OMPI_COMM_WORLD_RANK=" + std::to_string(rank);
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream stat(e.path() / "stat");
    std::string s;
    std::getline(stat, s);
    const size_t close = s.rfind(')');
    if (close == std::string::npos) continue;
    std::istringstream rest(s.substr(close + 2));
    char state;
    pid_t ppid = 0;
    rest >> state >> ppid;
    if (ppid != parent) continue;
    const std::string env = read_text(e.path() / "environ");
    size_t at = 0;
    while (at < env.size()) {
      const size_t end = env.find('\0', at);
      if (env.compare(at, (end == std::string::npos ? env.size() : end) - at, want) == 0)
        return static_cast<pid_t>(std::stol(name));
      if (end == std::string::npos) break;
      at = end + 1;
    }
  }
  return -1;
}

// Gone, or a zombie waiting for init to reap it (mpirun's children are re-parented when it exits).
bool running(pid_t pid) {
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string s;
  if (!std::getline(stat, s)) return false;
  const size_t close = s.rfind(')');
  return close != std::string::npos && close + 2 < s.size() && s[close + 2] != 'Z' && s[close + 2] != 'X';
}

// A long sky run under mpirun in the background (checkpoint every 5 steps); returns mpirun's pid
// once the first checkpoint exists, or -1.
pid_t start_long_run(const fs::path& out, const fs::path& err) {
  const std::string cmd = "exec " + mpirun(2) + kTrain.string() + " --config " +
                          (kConfigs / "quickstart_sky.json").string() + " " + sky_sets() +
                          " --set train.steps=100000 --set train.val_every=100000 --set train.checkpoint_every=5"
                          " --set train.batch_size=2 --out " + out.string() + " > /dev/null 2> " + err.string();
  const pid_t launcher = ::fork();
  if (launcher < 0) return -1;
  if (launcher == 0) {
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!fs::exists(out / "last.safetensors") && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // a few more checkpoints, mid-run
  return launcher;
}

// Waits up to 60 s for the launcher; kills it (and fails) when it does not stop.
int wait_launcher(pid_t launcher) {
  int status = 0;
  pid_t done = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while ((done = ::waitpid(launcher, &status, WNOHANG)) == 0 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  if (done == 0) {
    ::kill(launcher, SIGKILL);
    ::waitpid(launcher, &status, 0);
    ADD_FAILURE() << "mpirun did not stop within 60 s";
    return -1;
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(DataParallel, KillingOneRankStopsAllRanksAndKeepsTheLastCheckpoint) {
  const fs::path dir = scratch();
  const fs::path out = dir / "run", err = dir / "err.txt", last = out / "last.safetensors";
  const pid_t launcher = start_long_run(out, err);
  ASSERT_GT(launcher, 0);
  ASSERT_TRUE(fs::exists(last)) << read_text(err);
  const pid_t victim = rank_pid(launcher, 1), survivor = rank_pid(launcher, 0);
  ASSERT_GT(victim, 0);
  ASSERT_GT(survivor, 0);
  ASSERT_EQ(::kill(victim, SIGKILL), 0);
  const int code = wait_launcher(launcher);
  EXPECT_GT(code, 0);
  // Rank 0 ignores mpirun's SIGTERM (the trainer's stop handler) while it waits in an all-reduce
  // for the dead rank; mpirun's SIGKILL follows within seconds.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (running(survivor) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_FALSE(running(survivor)) << "rank 0 is still running";
  const std::string text = read_text(err);
  EXPECT_NE(text.find("rank 1"), std::string::npos) << text;
  EXPECT_NE(text.find("signal 9"), std::string::npos) << text;
  // The last checkpoint is whole: it parses, and it is the checkpoint of a step of this run.
  const auto info = sl::nn::read_checkpoint_info(last.string());
  EXPECT_EQ(info.stage, "sky_autoencoder");
  EXPECT_GE(info.step, 5);
  EXPECT_EQ(info.step % 5, 0);
  EXPECT_FALSE(sl::nn::read_safetensors(last.string()).tensors.empty());
}

// SIGTERM to ONE rank: every rank stops after the same step (the stop flag is all-reduced), rank 0
// saves last.safetensors at that step, and the job exits 0.
TEST(DataParallel, SigtermToOneRankStopsEveryRankAfterTheSameStep) {
  const fs::path dir = scratch();
  const fs::path out = dir / "run", err = dir / "err.txt";
  const pid_t launcher = start_long_run(out, err);
  ASSERT_GT(launcher, 0);
  ASSERT_TRUE(fs::exists(out / "last.safetensors")) << read_text(err);
  const pid_t rank1 = rank_pid(launcher, 1);
  ASSERT_GT(rank1, 0);
  ASSERT_EQ(::kill(rank1, SIGTERM), 0);
  EXPECT_EQ(wait_launcher(launcher), 0) << read_text(err);
  const std::string text = read_text(err);
  EXPECT_NE(text.find("stopped by signal at step"), std::string::npos) << text;
  const auto info = sl::nn::read_checkpoint_info((out / "last.safetensors").string());
  const Curve curve = train_curve(out);
  ASSERT_FALSE(curve.empty());
  EXPECT_EQ(info.step, curve.back()["step"].get<int64_t>()) << "saved at the step every rank stopped after";
}

}  // namespace

}  // namespace sl::test
