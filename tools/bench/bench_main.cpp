// streetlight-bench: benchmarks as a tool, never as timed tests. See bench.h.
#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "autodiff/vector_math.h"
#include "tools/bench/bench.h"
#include "util/compiled_isa.h"
#include "util/error.h"

namespace sl::bench {
namespace {
struct Entry {
  std::string summary;
  Command command;
};
std::map<std::string, Entry>& registry() {
  static std::map<std::string, Entry> r;
  return r;
}
void usage(FILE* out) {
  std::fprintf(out, "usage: streetlight-bench COMMAND [options]   (COMMAND --help for its options)\n\ncommands:\n");
  int width = 0;  // the longest command name, so that every summary starts in one column
  for (const auto& [name, e] : registry()) width = std::max(width, static_cast<int>(name.size()));
  for (const auto& [name, e] : registry()) std::fprintf(out, "  %-*s  %s\n", width, name.c_str(), e.summary.c_str());
}
// The CPU's model name as lscpu prints it (/proc/cpuinfo), so that every figure names its machine.
std::string cpu_model_name() {
  std::ifstream f("/proc/cpuinfo");
  for (std::string line; std::getline(f, line);)
    if (line.rfind("model name", 0) == 0) {
      const size_t colon = line.find(':');
      if (colon != std::string::npos) return line.substr(line.find_first_not_of(" \t", colon + 1));
    }
  return "unknown CPU";
}
}  // namespace

Registrar::Registrar(const char* name, const char* summary, Command command) {
  registry()[name] = Entry{summary, command};
}

}  // namespace sl::bench

int main(int argc, char** argv) {
  using namespace sl::bench;
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h") {
    usage(argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  auto it = registry().find(argv[1]);
  if (it == registry().end()) {
    std::fprintf(stderr, "error: unknown command '%s' (try streetlight-bench --help)\n", argv[1]);
    return 2;
  }
  const std::vector<std::string> args(argv + 2, argv + argc);
  const bool help = std::find_if(args.begin(), args.end(), [](const std::string& a) {
                      return a == "--help" || a == "-h";
                    }) != args.end();
  try {
    const int code = it->second.command(args);
    // After the figures (a bad-input error stays one line): the machine they were measured on, the
    // kernels this build was compiled for (-march) and the level STREETLIGHT_SIMD leaves the
    // run-time float32 transcendentals (autodiff/vector_math.h).
    if (code == 0 && !help)
      std::fprintf(stderr, "streetlight-bench %s ran on: %s, %s kernels (compiled), %s transcendentals, %d OpenMP threads\n",
                   argv[1], cpu_model_name().c_str(), sl::compiled_isa(), sl::vm::simd_level_name(sl::vm::active_simd_level()),
                   omp_get_max_threads());
    return code;
  } catch (const sl::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
