// Every executable answers --help (exit 0) and meets a bad flag with one line "error: ..." and
// exit 2 (docs/DESIGN.md, "Executables").
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <thread>

#include "data/image_io.h"
#include "data/sky_model.h"
#include "support/tiny_ldr_folder.h"
#include "tools/common/cli.h"
#include "util/error.h"
#include "util/math.h"

namespace sl::test {

namespace {

struct ProcessResult {
  int code;
  std::string out;
};

ProcessResult run(const std::string& cmd) {
  ProcessResult r{-1, ""};
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  while (fgets(buf.data(), buf.size(), p)) r.out += buf.data();
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

const std::string kBench = std::string(STREETLIGHT_BINARY_DIR) + "/tools/streetlight-bench";

// What the sun-glare bench's training tests share: a fresh temp folder named by `tag` and the process,
// the tiny labelled LDR panoramas in it (support/tiny_ldr_folder.h), their split (three train, one
// val), and the bench's command on them at the smallest sizes; the caller adds its flags.
struct GlareBenchRun {
  std::filesystem::path dir;
  std::string folder, split, base;
};

GlareBenchRun glare_bench_run(const std::string& tag, int steps) {
  GlareBenchRun g;
  g.dir = std::filesystem::temp_directory_path() / (tag + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(g.dir);
  g.folder = tiny_ldr_folder(g.dir.string());
  g.split = (g.dir / "split.json").string();
  std::ofstream(g.split) << R"({"train": ["t1.jpg", "t2.jpg", "b.jpg"], "val": ["a.jpg"]})";
  g.base = "OMP_NUM_THREADS=1 " + kBench + " sun-glare --data " + g.folder + " --split-file " + g.split +
           " --aimed 1 --near 1 --random 1 --batch 2 --width 4 --steps " + std::to_string(steps);
  return g;
}

std::vector<std::string> executables() {
  std::vector<std::string> out;
  const std::filesystem::path dir = std::filesystem::path(STREETLIGHT_BINARY_DIR) / "tools";
  if (!std::filesystem::exists(dir)) return out;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (e.is_regular_file() && name.rfind("streetlight-", 0) == 0 &&
        (std::filesystem::status(e.path()).permissions() & std::filesystem::perms::owner_exec) != std::filesystem::perms::none)
      out.push_back(e.path().string());
  }
  return out;
}

TEST(Executables, EveryToolAnswersHelpAndRejectsBadFlagsWithExitCode2) {
  const auto exes = executables();
  if (exes.empty()) GTEST_SKIP() << "no executables built in " << STREETLIGHT_BINARY_DIR << "/tools";
  for (const std::string& exe : exes) {
    const ProcessResult help = run(exe + " --help");
    EXPECT_EQ(help.code, 0) << exe << "\n" << help.out;
    EXPECT_NE(help.out.find("usage"), std::string::npos) << exe;
    // The usage line names the program once ("usage: streetlight-x streetlight-x ..." was a bug).
    const std::string name = std::filesystem::path(exe).filename().string();
    EXPECT_EQ(help.out.find("usage: " + name + " " + name), std::string::npos) << exe << "\n" << help.out;
    EXPECT_EQ(help.out.find("(repeatable) (repeatable)"), std::string::npos) << exe << "\n" << help.out;
    const ProcessResult bad = run(exe + " --definitely-not-a-flag");
    EXPECT_EQ(bad.code, 2) << exe << "\n" << bad.out;
    EXPECT_EQ(bad.out.rfind("error: ", 0), 0u) << exe << " printed:\n" << bad.out;
    EXPECT_EQ(std::count(bad.out.begin(), bad.out.end(), '\n'), 1) << exe << " printed:\n" << bad.out;
  }
}

// Every command that `streetlight-bench --help` lists answers its own --help with its usage and
// exit 0.
TEST(Executables, EveryBenchCommandAnswersHelp) {
  const std::string& bench = kBench;
  if (!std::filesystem::exists(bench)) GTEST_SKIP() << "streetlight-bench not built";
  const ProcessResult list = run(bench + " --help");
  ASSERT_EQ(list.code, 0) << list.out;
  const size_t start = list.out.find("commands:\n");
  ASSERT_NE(start, std::string::npos) << list.out;
  std::vector<std::string> commands;  // the first word of every line after "commands:"
  std::istringstream lines(list.out.substr(start + 10));
  for (std::string line, word; std::getline(lines, line);)
    if (std::istringstream(line) >> word) commands.push_back(word);
  EXPECT_GE(commands.size(), 10u) << list.out;
  for (const std::string& command : commands) {
    const ProcessResult help = run(bench + " " + command + " --help");
    EXPECT_EQ(help.code, 0) << command << "\n" << help.out;
    EXPECT_NE(help.out.find("usage: streetlight-bench " + command), std::string::npos) << command << "\n" << help.out;
  }
}

// The streetlight-bench subcommands parse their counts by hand; a count that is not a whole
// integer in range is the same one-line error naming the flag and the value, exit 2.
TEST(Executables, BenchCountsThatAreNotIntegersAreOneLineErrors) {
  const std::string& bench = kBench;
  if (!std::filesystem::exists(bench)) GTEST_SKIP() << "streetlight-bench not built";
  for (const std::string& args : {std::string("train-step --config x.json --steps 12abc"),
                                  std::string("train-step --config x.json --warmup -1"),
                                  std::string("predictor-step --batch two"),
                                  std::string("gen-mesh --triangles 0 --out never_written.glb")}) {
    const ProcessResult r = run(bench + " " + args);
    EXPECT_EQ(r.code, 2) << args << "\n" << r.out;
    EXPECT_EQ(r.out.rfind("error: ", 0), 0u) << args << "\n" << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << args << "\n" << r.out;
    EXPECT_NE(r.out.find("must be an integer in ["), std::string::npos) << args << "\n" << r.out;
  }
}

// streetlight-bench sun-glare scores the detector on val, or on new crops of train (--score-split
// train, its fit); the test split is never read: asking for it is a one-line error, exit 2.
TEST(Executables, BenchSunGlareNeverScoresTheTestSplitNorWhatItTrainedOn) {
  const std::string& bench = kBench;
  if (!std::filesystem::exists(bench)) GTEST_SKIP() << "streetlight-bench not built";
  const ProcessResult r = run(bench + " sun-glare --data d --split-file s.json --checkpoint c --score-split test");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out.rfind("error: ", 0), 0u) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_NE(r.out.find("--score-split"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("'test'"), std::string::npos) << r.out;
  // --train-split train+val (a final detector) may not be scored on val, which it trained on; it
  // accepts no other split.
  for (const std::string& args : {std::string("--train-split train+val"), std::string("--train-split test")}) {
    const ProcessResult t = run(bench + " sun-glare --data d --split-file s.json --out o " + args);
    EXPECT_EQ(t.code, 2) << args << "\n" << t.out;
    EXPECT_EQ(t.out.rfind("error: ", 0), 0u) << args << "\n" << t.out;
    EXPECT_EQ(std::count(t.out.begin(), t.out.end(), '\n'), 1) << args << "\n" << t.out;
    EXPECT_NE(t.out.find("--train-split"), std::string::npos) << args << "\n" << t.out;
  }
}

// streetlight-bench sun-glare resumes a cut-off training: a run stopped at step 2 of 4 (--stop-at,
// as a signal would stop it) leaves OUT.partial.safetensors and no OUT; the same command then ends
// with the very bytes of an uninterrupted run and removes the partial file. Other flags are refused
// with a one-line error naming the flag's key and the file.
TEST(Executables, BenchSunGlareResumesBitIdenticallyAndRefusesOtherFlags) {
  if (!std::filesystem::exists(kBench)) GTEST_SKIP() << "streetlight-bench not built";
  const GlareBenchRun g = glare_bench_run("sl_glare_resume", 4);
  const std::filesystem::path& dir = g.dir;
  const std::string& base = g.base;
  auto slurp = [](const std::filesystem::path& f) {
    std::ifstream in(f, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::filesystem::path whole = dir / "whole.safetensors", cut = dir / "cut.safetensors";
  const std::filesystem::path partial = dir / "cut.safetensors.partial.safetensors";
  ProcessResult r = run(base + " --out " + whole.string());
  ASSERT_EQ(r.code, 0) << r.out;
  r = run(base + " --out " + cut.string() + " --stop-at 2");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_FALSE(std::filesystem::exists(cut));
  ASSERT_TRUE(std::filesystem::exists(partial)) << r.out;
  r = run(base + " --out " + cut.string() + " --lr 1e-3");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out.rfind("error: ", 0), 0u) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_NE(r.out.find("lr"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(partial.filename().string()), std::string::npos) << r.out;
  r = run(base + " --out " + cut.string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("resuming from"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("at step 2"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(partial));
  const std::string a = slurp(whole), b = slurp(cut);
  EXPECT_GT(a.size(), 0u);
  EXPECT_TRUE(a == b) << "the resumed detector differs from the uninterrupted one";
  std::filesystem::remove_all(dir);
}

// --level-aimed K adds K level crops toward each training panorama's visible sun (2 panoramas here),
// the scores gain a set of level crops toward each val sun, and a partial run made with the flag
// resumes only with it.
TEST(Executables, BenchSunGlareLevelCropsAddToTrainingAndToTheScores) {
  if (!std::filesystem::exists(kBench)) GTEST_SKIP() << "streetlight-bench not built";
  const GlareBenchRun g = glare_bench_run("sl_glare_level", 2);
  const std::filesystem::path& dir = g.dir;
  const std::string& base = g.base;
  auto crops_of = [](const std::string& out) {
    const size_t at = out.find(" training crops (");
    if (at == std::string::npos) return -1;
    size_t begin = out.rfind(' ', at - 1);
    return std::stoi(out.substr(begin + 1, at - begin - 1));
  };
  const ProcessResult plain = run(base + " --out " + (dir / "plain.safetensors").string());
  ASSERT_EQ(plain.code, 0) << plain.out;
  const ProcessResult level = run(base + " --level-aimed 2 --out " + (dir / "level.safetensors").string());
  ASSERT_EQ(level.code, 0) << level.out;
  EXPECT_EQ(crops_of(level.out), crops_of(plain.out) + 4) << plain.out << level.out;
  const size_t section = level.out.find("level crops toward each visible sun (32 per panorama");
  ASSERT_NE(section, std::string::npos) << level.out;
  EXPECT_NE(level.out.find(": 32 crops, sun in view", section), std::string::npos) << level.out;
  const std::string cut = (dir / "cut.safetensors").string();
  ASSERT_EQ(run(base + " --level-aimed 2 --stop-at 1 --out " + cut).code, 0);
  const ProcessResult other = run(base + " --out " + cut);
  EXPECT_EQ(other.code, 2) << other.out;
  EXPECT_EQ(std::count(other.out.begin(), other.out.end(), '\n'), 1) << other.out;
  EXPECT_NE(other.out.find("level_aimed"), std::string::npos) << other.out;
  std::filesystem::remove_all(dir);
}

// The low-sun levers: --hdr-sun-crops K adds K crops toward the sun of each training HDR sky whose sun
// is hard (two clear skies here, one sun low, one high), and needs the HDR folder; --low-sun-weight
// weighs every training crop that shows a sun below --low-sun-below degrees, so below 90 it weighs
// every crop with a sun in view and below 0 none. The azimuth head's score says how many of its
// hidden units are alive.
TEST(Executables, BenchSunGlareLowSunLevers) {
  if (!std::filesystem::exists(kBench)) GTEST_SKIP() << "streetlight-bench not built";
  const GlareBenchRun g = glare_bench_run("sl_glare_low", 2);
  const std::filesystem::path& dir = g.dir;
  const std::filesystem::path skies = dir / "skies";
  std::filesystem::create_directories(skies);
  const double suns[3] = {15.0, 60.0, 25.0};  // elevations; the third sky is val
  const char* names[3] = {"low_1k.hdr", "high_1k.hdr", "val_1k.hdr"};
  for (int i = 0; i < 3; ++i) {
    data::SkyParams p;
    p.sun_elevation_rad = suns[i] * kPi / 180.0;
    p.sun_azimuth_rad = 0.7 * i;
    data::write_image((skies / names[i]).string(), data::PreethamSky(p).render(64, 128));
  }
  const std::string sky_split = (dir / "sky_split.json").string();
  std::ofstream(sky_split) << R"({"train": ["low_1k.hdr", "high_1k.hdr"], "val": ["val_1k.hdr"]})";
  const std::string base = g.base + " --azimuth-bins 4";
  const std::string hdr = " --hdr-data " + skies.string() + " --hdr-split-file " + sky_split + " --hdr-crops 1";
  auto number_before = [](const std::string& out, const std::string& what) {
    const size_t at = out.find(what);
    if (at == std::string::npos) return -1;
    const size_t begin = out.find_last_of(" (", at - 1);
    return std::stoi(out.substr(begin + 1, at - begin - 1));
  };
  const ProcessResult plain = run(base + hdr + " --out " + (dir / "plain.safetensors").string());
  ASSERT_EQ(plain.code, 0) << plain.out;
  const ProcessResult more = run(base + hdr + " --hdr-sun-crops 4 --out " + (dir / "more.safetensors").string());
  ASSERT_EQ(more.code, 0) << more.out;
  EXPECT_NE(more.out.find("8 crops toward the suns of 2 hard HDR skies"), std::string::npos) << more.out;
  EXPECT_EQ(number_before(more.out, " training crops ("), number_before(plain.out, " training crops (") + 8) << plain.out << more.out;
  EXPECT_NE(more.out.find("hidden units alive"), std::string::npos) << more.out;
  // Below 90 degrees every crop with a sun in view is weighed; below 0 none is.
  const ProcessResult all = run(base + hdr + " --low-sun-weight 4 --low-sun-below 90 --out " + (dir / "all.safetensors").string());
  ASSERT_EQ(all.code, 0) << all.out;
  EXPECT_EQ(number_before(all.out, " training crops show a sun below 90 deg"), number_before(all.out, " with the sun in view)"))
      << all.out;
  EXPECT_GT(number_before(all.out, " with the sun in view)"), 0) << all.out;
  const ProcessResult none = run(base + hdr + " --low-sun-weight 4 --low-sun-below 0 --out " + (dir / "none.safetensors").string());
  ASSERT_EQ(none.code, 0) << none.out;
  EXPECT_EQ(number_before(none.out, " training crops show a sun below 0 deg"), 0) << none.out;
  for (const std::string& bad : {std::string(" --hdr-sun-crops 4"), hdr + " --low-sun-weight -1", hdr + " --low-sun-below 91"}) {
    const ProcessResult r = run(base + bad + " --out " + (dir / "bad.safetensors").string());
    EXPECT_EQ(r.code, 2) << bad << "\n" << r.out;
    EXPECT_EQ(r.out.rfind("error: ", 0), 0u) << bad << "\n" << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << bad << "\n" << r.out;
  }
  std::filesystem::remove_all(dir);
}

// gen-mesh --kind: the benchmark set's procedural meshes (tools/bench/procedural_mesh.h) are a
// pure function of (kind, triangles, seed), reach the triangle target and overshoot it by at most
// one part, and an unknown kind is a one-line error.
TEST(Executables, GenMeshKindsAreDeterministicFromTheSeed) {
  const std::string& bench = kBench;
  if (!std::filesystem::exists(bench)) GTEST_SKIP() << "streetlight-bench not built";
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("sl_gen_mesh_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  auto slurp = [](const std::filesystem::path& f) {
    std::ifstream in(f, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  for (const std::string kind : {"machine", "facade", "blob", "foliage", "terrain"}) {
    std::string files[3];
    for (int i = 0; i < 3; ++i) {
      const std::filesystem::path out = dir / (kind + std::to_string(i) + ".glb");
      const ProcessResult r = run(bench + " gen-mesh --kind " + kind + " --triangles 3000 --seed " +
                                  (i == 2 ? "2" : "1") + " --out " + out.string());
      ASSERT_EQ(r.code, 0) << kind << "\n" << r.out;
      const size_t at = r.out.find("wrote ");
      ASSERT_NE(at, std::string::npos) << r.out;
      const long triangles = std::stol(r.out.substr(at + 6));
      EXPECT_GE(triangles, 3000) << kind;
      EXPECT_LE(triangles, kind == "facade" ? 3000 + 40000 : 3600) << kind;  // whole parts; a building is large
      files[i] = slurp(out);
    }
    EXPECT_FALSE(files[0].empty()) << kind;
    EXPECT_EQ(files[0], files[1]) << kind << ": the same seed must give the same file";
    EXPECT_NE(files[0], files[2]) << kind << ": another seed must give another mesh";
  }
  const ProcessResult bad = run(bench + " gen-mesh --kind nope --triangles 10 --out " + (dir / "x.glb").string());
  EXPECT_EQ(bad.code, 2) << bad.out;
  EXPECT_EQ(bad.out.rfind("error: ", 0), 0u) << bad.out;
  EXPECT_EQ(std::count(bad.out.begin(), bad.out.end(), '\n'), 1) << bad.out;
  std::filesystem::remove_all(dir);
}

TEST(CliParseInteger, TakesTheWholeValueInRangeOrNamesIt) {
  EXPECT_EQ(cli::parse_integer("x: --n", "42", 1, 100), 42);
  EXPECT_EQ(cli::parse_integer("x: --n", "-3", -5, 5), -3);
  for (const char* bad : {"", "4.5", "12abc", "101", "0", " 7"}) {
    try {
      cli::parse_integer("x: --n", bad, 1, 100);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("x: --n must be an integer in [1, 100], got '" + std::string(bad) + "'"),
                std::string::npos)
          << e.what();
    }
  }
}

TEST(CliParseNumber, TakesTheWholeFiniteValueInRangeOrNamesIt) {
  EXPECT_EQ(cli::parse_number("x: --s", "0.25", 0.0, 1.0), 0.25);
  EXPECT_EQ(cli::parse_number("x: --s", "2e-3", 0.0, 1.0), 2e-3);
  EXPECT_EQ(cli::parse_number("x: --s", "1", 0.0, 1.0), 1.0);
  for (const char* bad : {"", "abc", "0.5x", "1.5", "-0.1", " 0.5", "nan", "inf"}) {
    try {
      cli::parse_number("x: --s", bad, 0.0, 1.0);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("x: --s must be a number in [0, 1], got '" + std::string(bad) + "'"), std::string::npos)
          << e.what();
    }
  }
}

}  // namespace

}  // namespace sl::test

namespace sl::test {
// A resumed run's progress counts from where this process began: 3 items past a checkpoint at
// 5000 of 6000 are 3 items (not 5003) over this process's time, so its ETA is ~1000 items long.
TEST(CliProgress, RateCountsFromTheFirstUpdateNotFromZero) {
  cli::Progress resumed("x", 6000, 1e9);
  cli::Progress fresh("y", 6000, 1e9);
  ::testing::internal::CaptureStderr();
  resumed.update(5001);
  fresh.update(1);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  resumed.update(5003);
  fresh.update(3);
  ::testing::internal::GetCapturedStderr();
  // Both counted 3 items (deterministic: no clock involved).
  EXPECT_EQ(resumed.counted(), 3);
  EXPECT_EQ(fresh.counted(), 3);
  // At least 50 ms passed, so 3 items are at most 60 per second whatever the load; counting the
  // checkpoint's 5000 items would give about 10^5.
  const double a = resumed.rate();
  EXPECT_GT(a, 0.0);
  EXPECT_LE(a, 3.0 / 0.05) << "the rate counted the checkpoint's items";
}

// The last line of a run names what this process did: a run stopped by a signal at step 236 of
// 20000, resumed from 200, says so; a finished one says done with the items it counted.
TEST(CliProgress, FinishSaysWhereAStoppedRunStoppedAndCountsOnlyThisProcesssItems) {
  cli::Progress stopped("train lighting", 20000, 1e9);
  cli::Progress finished("eval", 8, 1e9);
  ::testing::internal::CaptureStderr();
  stopped.update(201);
  stopped.update(236);
  stopped.finish();
  finished.update(1);
  finished.update(8);
  finished.finish();
  const std::string text = ::testing::internal::GetCapturedStderr();
  EXPECT_NE(text.find("train lighting stopped at 236/20000: 36 in "), std::string::npos) << text;
  EXPECT_EQ(text.find("train lighting done"), std::string::npos) << text;
  EXPECT_NE(text.find("eval done: 8 in "), std::string::npos) << text;
}
}  // namespace sl::test
