// util/file.h: atomic files and folders, and the sweep of temporary files left by killed runs.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "util/error.h"
#include "util/file.h"

namespace fs = std::filesystem;

namespace sl::test {
namespace {

fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("sl_file_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string read_all(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

int entries(const fs::path& d) {
  int n = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(d)) ++n;
  return n;
}

// The pid of a process that has exited and been reaped.
pid_t dead_pid() {
  const pid_t pid = ::fork();
  if (pid == 0) ::_exit(0);
  int status = 0;
  ::waitpid(pid, &status, 0);
  return pid;
}

TEST(AtomicFile, WritesTheWholeFileAndLeavesNoTemporary) {
  const fs::path d = fresh_dir("write");
  write_file_atomic((d / "a.txt").string(), "hello\n");
  EXPECT_EQ(read_all(d / "a.txt"), "hello\n");
  EXPECT_EQ(entries(d), 1);
  fs::remove_all(d);
}

TEST(AtomicFile, AnExceptionBeforeCommitKeepsTheOldFileAndRemovesTheTemporary) {
  const fs::path d = fresh_dir("abort");
  write_file_atomic((d / "a.txt").string(), "old");
  try {
    AtomicFile f((d / "a.txt").string());
    f.write("new", 3);
    EXPECT_TRUE(fs::exists(f.temp_path()));
    throw std::runtime_error("killed");
  } catch (const std::runtime_error&) {
  }
  EXPECT_EQ(read_all(d / "a.txt"), "old");
  EXPECT_EQ(entries(d), 1);
  fs::remove_all(d);
}

TEST(AtomicDirectory, AppearsOnlyOnCommit) {
  const fs::path d = fresh_dir("dir");
  {
    AtomicDirectory out((d / "out").string());
    write_file_atomic(out.file("x.txt"), "x");
    EXPECT_FALSE(fs::exists(d / "out"));
  }
  EXPECT_EQ(entries(d), 0);  // not committed: nothing left
  AtomicDirectory out((d / "out").string());
  write_file_atomic(out.file("x.txt"), "x");
  out.commit();
  EXPECT_EQ(read_all(d / "out" / "x.txt"), "x");
  EXPECT_EQ(entries(d), 1);
  fs::remove_all(d);
}

TEST(SweepStaleTempFiles, RemovesTheTemporariesOfDeadProcessesOnly) {
  const fs::path d = fresh_dir("sweep");
  const std::string dead = std::to_string(dead_pid()), alive = std::to_string(::getppid());
  write_file_atomic((d / ("." + std::string("last.safetensors.tmp.") + dead + ".0")).string(), "x");
  write_file_atomic((d / (".last.safetensors.tmp." + dead)).string(), "x");  // the name before util/file.h
  fs::create_directories(d / (".out.tmp." + dead + ".3"));
  write_file_atomic((d / (".best.safetensors.tmp." + alive + ".0")).string(), "x");
  write_file_atomic((d / "last.safetensors").string(), "x");
  write_file_atomic((d / "notes.tmp.txt").string(), "x");
  EXPECT_EQ(sweep_stale_temp_files(d.string()), 3);
  EXPECT_TRUE(fs::exists(d / (".best.safetensors.tmp." + alive + ".0")));
  EXPECT_TRUE(fs::exists(d / "last.safetensors"));
  EXPECT_TRUE(fs::exists(d / "notes.tmp.txt"));
  EXPECT_EQ(entries(d), 3);
  EXPECT_EQ(sweep_stale_temp_files((d / "missing").string()), 0);
  fs::remove_all(d);
}

}  // namespace
}  // namespace sl::test
