// The shared parts of the harnesses: the target table, violation(), the scratch folder.
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "tests/fuzz/harness/fuzz_harness.h"

namespace sl::test {

namespace fs = std::filesystem;

const std::vector<Target>& targets() {
  static const std::vector<Target> all = {
      {"safetensors", &fuzz_safetensors}, {"gltf", &fuzz_gltf},       {"image", &fuzz_image},
      {"kitti", &fuzz_kitti},             {"calibration_json", &fuzz_calibration_json},
      {"dataset", &fuzz_dataset},         {"config", &fuzz_config},   {"rays", &fuzz_rays},
      {"batch_list", &fuzz_batch_list},   {"sun_labels", &fuzz_sun_labels}, {"tflite", &fuzz_tflite},
  };
  return all;
}

void violation(const char* target, const std::string& what) {
  std::fprintf(stderr, "fuzz invariant violated in %s: %s\n", target, what.c_str());
  std::fflush(stderr);
  std::abort();
}

namespace {
struct Scratch {
  std::string dir;
  Scratch() {
    const fs::path base = fs::temp_directory_path() / ("streetlight-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(base);
    dir = base.string();
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};
}  // namespace

const std::string& fuzz_scratch_dir() {
  static const Scratch scratch;
  return scratch.dir;
}

std::string write_scratch(const std::string& name, const uint8_t* data, size_t size) {
  const fs::path path = fs::path(fuzz_scratch_dir()) / name;
  fs::create_directories(path.parent_path());
  // A new file, not a truncated one: ext4 flushes a file truncated and rewritten to disk when it
  // is closed (auto_da_alloc), which held every target at ~300 executions per second.
  std::error_code ec;
  fs::remove(path, ec);
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  f.close();
  if (!f) violation("scratch", "cannot write " + path.string());
  return path.string();
}

}  // namespace sl::test
