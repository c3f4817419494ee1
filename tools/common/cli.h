// The shared style of every Streetlight executable (docs/DESIGN.md, "Executables").
//
// Contract:
// - Args: --help prints the synopsis and every flag, and --version the release (util/version.h,
//   "streetlight-insert 0.6.0"); both return false from parse(). An unknown
//   flag is an error naming it and the nearest known flag; a flag missing its value is an
//   error. Flags may repeat when declared repeatable (--set, --checkpoint).
// - run_main(): sl::Error -> one line "error: <message>" on stderr and exit 2 (bad input);
//   any other exception -> "error: ..." and exit 1 (failure at run time).
// - --version also says which released weights a run without --checkpoint would load
//   (tools/common/released_models.h, which this header includes).
// - Progress: on a terminal, one self-overwriting bar with rate and ETA; otherwise a plain line
//   at most every `plain_interval_s` seconds (and at the end), so logs stay short. The rate counts
//   from where this process began: the first update's `done` − 1 (a resumed run's first step is
//   its checkpoint's + 1), so a resumed run's ETA is its own, not the whole run's over its time.
// - parse_integer(what, value, lo, hi): the whole of `value` as an integer in [lo, hi], else
//   sl::Error "<what> must be an integer in [lo, hi], got '<value>'" (for hand-parsed flags such
//   as the streetlight-bench subcommands').
// - parse_number(what, value, lo, hi): the whole of `value` as a finite number in [lo, hi], else
//   sl::Error "<what> must be a number in [lo, hi], got '<value>'".
#pragma once
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "tools/common/released_models.h"

namespace sl::cli {

int64_t parse_integer(const std::string& what, const std::string& value, int64_t lo, int64_t hi);
double parse_number(const std::string& what, const std::string& value, double lo, double hi);

struct Flag {
  std::string name;        // "--config"
  std::string value_name;  // "FILE"; empty for a switch
  std::string help;
  bool repeatable = false;
};

class Args {
 public:
  Args(std::string program, std::string synopsis, std::vector<Flag> flags);
  bool parse(int argc, char** argv);  // false when --help was printed

  bool has(const std::string& name) const;
  std::string get(const std::string& name, const std::string& fallback = "") const;
  std::vector<std::string> all(const std::string& name) const;
  double number(const std::string& name, double fallback) const;
  // A comma-separated list of numbers ("0.55,0.7"), each inside the open interval (lo, hi);
  // "none" gives an empty list.
  std::vector<double> numbers(const std::string& name, const std::vector<double>& fallback, double lo,
                              double hi) const;
  int64_t integer(const std::string& name, int64_t fallback) const;
  std::string help_text() const;

 private:
  std::string program_, synopsis_;
  std::vector<Flag> flags_;
  std::map<std::string, std::vector<std::string>> values_;
};

int run_main(const std::function<int()>& body);

class Progress {
 public:
  Progress(std::string label, int64_t total, double plain_interval_s = 10.0);
  void update(int64_t done, const std::string& extra = "");
  // One line: "LABEL done: N in Ts" when the last update reached the total, else "LABEL stopped
  // at DONE/TOTAL: N in Ts"; N = counted().
  void finish(const std::string& extra = "");
  // The items this process counted: the last update's `done` minus the first's `done` − 1 (0
  // before any update), and them per second since construction.
  int64_t counted() const { return base_ < 0 ? 0 : done_ - base_; }
  double rate() const;

 private:
  using clock = std::chrono::steady_clock;
  std::string label_;
  int64_t total_;
  double interval_;
  bool tty_;
  clock::time_point start_, last_;
  int64_t base_ = -1;  // `done` before this process's first item (set by the first update)
  int64_t done_ = 0;
};

}  // namespace sl::cli
