#include "tools/common/config.h"

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "util/error.h"

namespace sl::cli {

using json = nlohmann::json;

namespace {

size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

const char* type_name(const json& j) {
  if (j.is_boolean()) return "boolean";
  if (j.is_number_integer()) return "integer";
  if (j.is_number()) return "number";
  if (j.is_string()) return "string";
  if (j.is_array()) return "array";
  if (j.is_object()) return "object";
  return "null";
}

// A value for a message. --set values that are not JSON are kept as raw strings, which may hold
// invalid UTF-8; plain dump() would throw json::type_error on them.
std::string shown(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

bool compatible(const json& def, const json& val) {
  if (def.is_null()) return true;  // a default of null accepts anything (optional paths)
  if (def.is_number_float()) return val.is_number();
  if (def.is_number_integer()) return val.is_number_integer();
  if (def.is_boolean()) return val.is_boolean();
  if (def.is_string()) return val.is_string() || val.is_null();
  if (def.is_array()) return val.is_array();
  if (def.is_object()) return val.is_object();
  return false;
}

void merge_into(json& target, const json& defaults, const json& src, const std::string& prefix,
                const std::vector<std::string>& all_paths, const std::string& origin) {
  SL_CHECK(src.is_object(), origin, ": ", prefix.empty() ? "the config" : "key '" + prefix + "'",
           " must be an object, got ", type_name(src));
  for (auto it = src.begin(); it != src.end(); ++it) {
    const std::string path = prefix.empty() ? it.key() : prefix + "." + it.key();
    if (!defaults.contains(it.key())) {
      const std::string near = nearest(path, all_paths);
      fail(origin, ": unknown key '", path, "'", near.empty() ? "" : " (did you mean '" + near + "'?)");
    }
    const json& def = defaults[it.key()];
    if (def.is_object() && !def.empty()) {
      merge_into(target[it.key()], def, it.value(), path, all_paths, origin);
      continue;
    }
    SL_CHECK(compatible(def, it.value()), origin, ": key '", path, "' expects ", type_name(def), ", got ",
             type_name(it.value()), " (", shown(it.value()), ")");
    target[it.key()] = it.value();
  }
}

}  // namespace

std::vector<std::string> key_paths(const json& j, const std::string& prefix) {
  std::vector<std::string> out;
  if (!j.is_object()) return out;
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string path = prefix.empty() ? it.key() : prefix + "." + it.key();
    out.push_back(path);
    for (const auto& p : key_paths(it.value(), path)) out.push_back(p);
  }
  return out;
}

std::string nearest(const std::string& key, const std::vector<std::string>& candidates) {
  std::string best;
  size_t best_d = SIZE_MAX;
  const std::string leaf = key.substr(key.rfind('.') == std::string::npos ? 0 : key.rfind('.') + 1);
  const size_t limit = std::max<size_t>(3, key.size() / 3);
  // An edit distance is at least the difference of the lengths: a distance that cannot beat the
  // best so far, nor pass the limit, is not computed (same answer; a long unknown key no longer
  // costs its length times every key's length, for every key).
  const auto length_gap = [](const std::string& a, const std::string& b) {
    return a.size() > b.size() ? a.size() - b.size() : b.size() - a.size();
  };
  for (const auto& c : candidates) {
    const std::string cleaf = c.substr(c.rfind('.') == std::string::npos ? 0 : c.rfind('.') + 1);
    const size_t bound = std::min(best_d, limit + 1);
    size_t d = length_gap(leaf, cleaf) + 1 < bound ? edit_distance(leaf, cleaf) + 1 : SIZE_MAX;
    if (length_gap(key, c) < std::min(d, bound)) d = std::min(d, edit_distance(key, c));
    if (d < best_d) {
      best_d = d;
      best = c;
    }
  }
  return best_d <= limit ? best : "";
}

Config::Config(json defaults) : defaults_(std::move(defaults)), value_(defaults_) {
  SL_CHECK(defaults_.is_object(), "Config: defaults must be a JSON object");
}

void Config::merge(const json& overrides, const std::string& origin) {
  merge_into(value_, defaults_, overrides, "", key_paths(defaults_), origin);
}

std::vector<ConfigFile> read_config_chain(const std::string& path) {
  std::vector<ConfigFile> chain;  // the extending file first, until it is reversed
  std::vector<std::string> selves;  // each read file's normalised path, to find a cycle
  std::string extended_by;  // the file whose "extends" named p, for the message when p cannot be opened
  for (std::string p = path;;) {
    std::ifstream in(p);
    if (extended_by.empty()) SL_CHECK(in.good(), "cannot open config file '", p, "'");
    SL_CHECK(in.good(), "config file '", extended_by, "' extends '", p, "', which cannot be opened");
    json j;
    try {
      j = json::parse(in, nullptr, true, /*ignore_comments=*/true);
    } catch (const json::exception& e) {  // parse_error, and out_of_range for a number past double
      fail("config file '", p, "' is not valid JSON: ", e.what());
    }
    std::string base_path;
    if (j.is_object() && j.contains("extends")) {
      const json& base = j["extends"];
      SL_CHECK(base.is_string() && !base.get<std::string>().empty(), "config file '", p,
               "': \"extends\" expects the path of another config file, got ", base.dump());
      base_path = (std::filesystem::path(p).parent_path() / base.get<std::string>()).lexically_normal().string();
      selves.push_back(std::filesystem::path(p).lexically_normal().string());
      SL_CHECK(chain.size() < 16, "config file '", p, "': \"extends\" chains deeper than 16 files");
      SL_CHECK(std::find(selves.begin(), selves.end(), base_path) == selves.end(), "config file '", p, "' extends '",
               base_path, "', which is already being read (a cycle)");
      j.erase("extends");
    }
    chain.push_back({p, std::move(j)});
    if (base_path.empty()) break;
    extended_by = p;
    p = base_path;
  }
  std::reverse(chain.begin(), chain.end());
  return chain;
}

void Config::merge_file(const std::string& path) {
  for (const ConfigFile& f : read_config_chain(path)) merge(f.content, "config file '" + f.path + "'");
}

void Config::set(const std::string& assignment) {
  const size_t eq = assignment.find('=');
  SL_CHECK(eq != std::string::npos && eq > 0, "--set expects key.path=value, got '", assignment, "'");
  const std::string path = assignment.substr(0, eq), text = assignment.substr(eq + 1);
  json value;
  try {
    value = json::parse(text);
  } catch (const json::exception&) {  // not JSON, or a number past double ("1e999")
    value = text;  // a bare string
  }
  json nested = value;
  std::string rest = path;
  std::vector<std::string> parts;
  for (size_t p; (p = rest.find('.')) != std::string::npos; rest = rest.substr(p + 1)) parts.push_back(rest.substr(0, p));
  parts.push_back(rest);
  for (size_t i = parts.size(); i-- > 0;) nested = json{{parts[i], nested}};
  merge(nested, "--set " + path);
}

const json& Config::at(const std::string& path) const {
  const json* j = &value_;
  std::string rest = path;
  while (true) {
    const size_t p = rest.find('.');
    const std::string key = rest.substr(0, p);
    SL_CHECK(j->is_object() && j->contains(key), "config has no key '", path, "'");
    j = &(*j)[key];
    if (p == std::string::npos) return *j;
    rest = rest.substr(p + 1);
  }
}

double Config::number(const std::string& path) const {
  const json& j = at(path);
  SL_CHECK(j.is_number(), "config key '", path, "' is ", type_name(j), ", expected a number");
  return j.get<double>();
}

int64_t Config::integer(const std::string& path) const {
  const json& j = at(path);
  SL_CHECK(j.is_number_integer(), "config key '", path, "' is ", type_name(j), ", expected an integer");
  return j.get<int64_t>();
}

bool Config::boolean(const std::string& path) const {
  const json& j = at(path);
  SL_CHECK(j.is_boolean(), "config key '", path, "' is ", type_name(j), ", expected a boolean");
  return j.get<bool>();
}

std::string Config::string(const std::string& path) const {
  const json& j = at(path);
  if (j.is_null()) return "";
  SL_CHECK(j.is_string(), "config key '", path, "' is ", type_name(j), ", expected a string");
  return j.get<std::string>();
}

std::vector<double> Config::numbers(const std::string& path) const {
  const json& j = at(path);
  SL_CHECK(j.is_array(), "config key '", path, "' is ", type_name(j), ", expected an array of numbers");
  std::vector<double> out;
  for (const auto& v : j) {
    SL_CHECK(v.is_number(), "config key '", path, "' holds ", shown(v), ", expected numbers only");
    out.push_back(v.get<double>());
  }
  return out;
}

}  // namespace sl::cli
