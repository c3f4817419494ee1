// Helpers shared by the data tests: a per-process scratch folder and the shared-data root.
#pragma once
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>

namespace sl::test {

// A scratch folder unique to this process (test cases may run as parallel processes).
inline std::filesystem::path scratch_dir() {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("streetlight_data_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir;
}

inline std::string scratch(const std::string& name) { return (scratch_dir() / name).string(); }

inline std::string shared_data(const std::string& relative) {
  return std::string(STREETLIGHT_SHARED_DATA) + "/" + relative;
}

inline void truncate_file(const std::string& path, double keep_fraction) {
  const auto size = std::filesystem::file_size(path);
  std::filesystem::resize_file(path, static_cast<uintmax_t>(size * keep_fraction));
}

inline void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out << bytes;
}

// Runs scripts/SCRIPT with ARGS under Debian's interpreter (which scripts/install_deps.sh gives numpy;
// else the first python3 on PATH): its exit code (-1 when it did not exit) and its stdout and stderr.
inline std::pair<int, std::string> run_python_script(const std::string& script, const std::string& args) {
  const std::string python = std::filesystem::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
  FILE* p = popen((python + " " + STREETLIGHT_SOURCE_DIR + "/scripts/" + script + " " + args + " 2>&1").c_str(), "r");
  std::string text;
  char buf[512];
  while (p && fgets(buf, sizeof buf, p)) text += buf;
  const int status = p ? pclose(p) : -1;
  return {status != -1 && WIFEXITED(status) ? WEXITSTATUS(status) : -1, text};
}

}  // namespace sl::test
