// streetlight-bench subcommands. Each tools/bench/<name>.cpp registers one or more commands:
//   static sl::bench::Registrar reg("trace", "closest/any-hit throughput", &run_trace);
// A command gets the arguments after its name and returns the process exit code
// (0 ok, 2 bad input, 1 run-time failure). Results go to stdout (one JSON object per line
// with --json), progress to stderr.
#pragma once
#include <string>
#include <vector>

namespace sl::bench {

using Command = int (*)(const std::vector<std::string>& args);

struct Registrar {
  Registrar(const char* name, const char* summary, Command command);
};

}  // namespace sl::bench
