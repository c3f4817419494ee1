// streetlight-bench: benchmarks as a tool, never as timed tests. See bench.h.
#include <algorithm>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "tools/bench/bench.h"
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
  try {
    return it->second.command(std::vector<std::string>(argv + 2, argv + argc));
  } catch (const sl::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
