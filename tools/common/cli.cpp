#include "tools/common/cli.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>

#include <unistd.h>

#include <cstdio>
#include <exception>

#include "tools/common/config.h"
#include "util/error.h"
#include "util/version.h"

namespace sl::cli {

Args::Args(std::string program, std::string synopsis, std::vector<Flag> flags)
    : program_(std::move(program)), synopsis_(std::move(synopsis)), flags_(std::move(flags)) {}

std::string Args::help_text() const {
  // A synopsis may already start with the program's name (several lines of usage do).
  const bool named = synopsis_.rfind(program_ + " ", 0) == 0;
  std::string s = "usage: " + (named ? synopsis_ : program_ + " " + synopsis_) + "\n\noptions:\n";
  for (const Flag& f : flags_) {
    std::string left = "  " + f.name + (f.value_name.empty() ? "" : " " + f.value_name);
    if (left.size() < 30) left.resize(30, ' ');
    s += left + " " + f.help + (f.repeatable ? " (repeatable)" : "") + "\n";
  }
  s += "  --help                       print this help\n";
  s += "  --version                    print the release (CHANGELOG.md)\n";
  return s;
}

bool Args::parse(int argc, char** argv) {
  std::vector<std::string> names;
  for (const Flag& f : flags_) names.push_back(f.name);
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::fputs(help_text().c_str(), stdout);
      return false;
    }
    if (a == "--version") {
      // The release, and the weights a run without --checkpoint would load.
      std::printf("%s %s\n", program_.c_str(), version());
      std::string model;
      try {
        model = released_model_path();
      } catch (const Error& e) {
        model = std::string("none: ") + e.what();
      }
      const std::string glare = released_sun_glare_path();
      std::printf("released model: %s\nsun-glare detector: %s\n", model.c_str(),
                  glare.empty() ? "none found" : glare.c_str());
      return false;
    }
    std::string value;
    bool inline_value = false;
    if (const size_t eq = a.find('='); a.rfind("--", 0) == 0 && eq != std::string::npos) {
      value = a.substr(eq + 1);
      a = a.substr(0, eq);
      inline_value = true;
    }
    const Flag* flag = nullptr;
    for (const Flag& f : flags_)
      if (f.name == a) flag = &f;
    if (!flag) {
      const std::string near = nearest(a, names);
      fail(program_, ": unknown option '", a, "'", near.empty() ? "" : " (did you mean '" + near + "'?)",
           "; try --help");
    }
    if (!flag->value_name.empty() && !inline_value) {
      SL_CHECK(i + 1 < argc, program_, ": option ", a, " needs a value (", flag->value_name, ")");
      value = argv[++i];
    }
    auto& slot = values_[a];
    SL_CHECK(flag->repeatable || slot.empty(), program_, ": option ", a, " given more than once");
    slot.push_back(value);
  }
  return true;
}

bool Args::has(const std::string& name) const { return values_.count(name) > 0; }

std::string Args::get(const std::string& name, const std::string& fallback) const {
  auto it = values_.find(name);
  return it == values_.end() ? fallback : it->second.back();
}

std::vector<std::string> Args::all(const std::string& name) const {
  auto it = values_.find(name);
  return it == values_.end() ? std::vector<std::string>{} : it->second;
}

namespace {

// True when std::stoll reads the whole of `v` (which may start with white space).
bool whole_integer(const std::string& v, long long* out) {
  try {
    size_t used = 0;
    *out = std::stoll(v, &used);
    return used == v.size();
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace

double Args::number(const std::string& name, double fallback) const {
  if (!has(name)) return fallback;
  const std::string v = get(name);
  try {
    size_t used = 0;
    const double d = std::stod(v, &used);
    if (used == v.size()) return d;
  } catch (const std::exception&) {
  }
  fail(program_, ": option ", name, " expects a number, got '", v, "'");
}

std::vector<double> Args::numbers(const std::string& name, const std::vector<double>& fallback, double lo,
                                  double hi) const {
  if (!has(name)) return fallback;
  const std::string v = get(name);
  std::vector<double> out;
  if (v == "none") return out;
  size_t pos = 0;
  while (pos <= v.size()) {
    const size_t end = std::min(v.find(',', pos), v.size());
    const std::string item = v.substr(pos, end - pos);
    try {
      size_t used = 0;
      const double d = std::stod(item, &used);
      if (used != item.size() || item.empty()) throw std::invalid_argument(item);
      out.push_back(d);
    } catch (const std::exception&) {
      fail(program_, ": option ", name, " expects numbers separated by commas (or 'none'), got '", v, "'");
    }
    pos = end + 1;
  }
  for (const double d : out)
    if (!(d > lo && d < hi)) fail(program_, ": option ", name, ": each value must lie in (", lo, ", ", hi, "), got ", d);
  return out;
}

int64_t Args::integer(const std::string& name, int64_t fallback) const {
  if (!has(name)) return fallback;
  const std::string v = get(name);
  long long d = 0;
  if (!whole_integer(v, &d)) fail(program_, ": option ", name, " expects an integer, got '", v, "'");
  return d;
}

int64_t parse_integer(const std::string& what, const std::string& value, int64_t lo, int64_t hi) {
  long long v = 0;
  const bool whole = !value.empty() && !std::isspace(static_cast<unsigned char>(value.front())) &&
                     whole_integer(value, &v);
  SL_CHECK(whole && v >= lo && v <= hi, what, " must be an integer in [", lo, ", ", hi, "], got '", value, "'");
  return v;
}

double parse_number(const std::string& what, const std::string& value, double lo, double hi) {
  char* end = nullptr;
  const double v = value.empty() || std::isspace(static_cast<unsigned char>(value.front())) ? std::nan("")
                                                                                             : std::strtod(value.c_str(), &end);
  SL_CHECK(end && *end == '\0' && std::isfinite(v) && v >= lo && v <= hi, what, " must be a number in [", lo, ", ", hi,
           "], got '", value, "'");
  return v;
}

int run_main(const std::function<int()>& body) {
  try {
    return body();
  } catch (const sl::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}

Progress::Progress(std::string label, int64_t total, double plain_interval_s)
    : label_(std::move(label)), total_(total), interval_(plain_interval_s), tty_(isatty(STDERR_FILENO) != 0) {
  start_ = last_ = clock::now();
}

double Progress::rate() const {
  const double elapsed = std::chrono::duration<double>(clock::now() - start_).count();
  return elapsed > 0 ? static_cast<double>(counted()) / elapsed : 0.0;
}

void Progress::update(int64_t done, const std::string& extra) {
  if (base_ < 0) base_ = std::max<int64_t>(0, done - 1);
  done_ = done;
  const auto now = clock::now();
  const double since = std::chrono::duration<double>(now - last_).count();
  if (!tty_ && since < interval_ && done < total_) return;
  if (tty_ && since < 0.1 && done < total_) return;
  last_ = now;
  const double rate = this->rate();
  const double eta = rate > 0 ? (total_ - done) / rate : 0;
  if (tty_) {
    const int width = 28, filled = total_ > 0 ? int(width * done / total_) : 0;
    std::fprintf(stderr, "\r%s [%s%s] %lld/%lld %.2f it/s ETA %.0fs %s\033[K", label_.c_str(),
                 std::string(filled, '#').c_str(), std::string(width - filled, '.').c_str(), (long long)done,
                 (long long)total_, rate, eta, extra.c_str());
  } else {
    std::fprintf(stderr, "%s %lld/%lld (%.2f it/s, ETA %.0fs) %s\n", label_.c_str(), (long long)done,
                 (long long)total_, rate, eta, extra.c_str());
  }
  std::fflush(stderr);
}

void Progress::finish(const std::string& extra) {
  const double elapsed = std::chrono::duration<double>(clock::now() - start_).count();
  if (tty_) std::fputs("\n", stderr);
  // A run stopped early (a signal, an error the caller survived) says where it stopped: "done:
  // 20000" after 236 steps would be a lie.
  if (done_ < total_)
    std::fprintf(stderr, "%s stopped at %lld/%lld: %lld in %.1fs %s\n", label_.c_str(), (long long)done_,
                 (long long)total_, (long long)counted(), elapsed, extra.c_str());
  else
    std::fprintf(stderr, "%s done: %lld in %.1fs %s\n", label_.c_str(), (long long)counted(), elapsed, extra.c_str());
}

}  // namespace sl::cli
