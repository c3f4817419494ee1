// Helpers shared by the data tests: a per-process scratch folder and the shared-data root.
#pragma once
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

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

}  // namespace sl::test
