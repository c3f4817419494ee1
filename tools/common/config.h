// JSON configs validated against their defaults (docs/DESIGN.md, "Executables share one style").
//
// Contract: a Config starts from a defaults object that lists EVERY valid key with its default
// value and type. merge_file() and set() apply overrides. A key the defaults do not have is an
// error naming the key path and the nearest valid key ("did you mean ..."). A value whose JSON
// type differs from the default's is an error naming the key path and both types. Integers are
// accepted where a float is expected, not the reverse. --set values parse as JSON, falling back
// to a plain string ("--set model.norm=batch"). Typed getters throw naming the key path.
// A config file may start from another: a top-level "extends": "base.json" (a path relative to
// the extending file's folder) merges the base file first, then the rest of the file over it.
// Chains are allowed; a cycle, a missing base or a non-string "extends" is an error naming the
// file. "extends" itself is not a config key and is not stored. read_config_chain() gives the
// chain's files themselves, for a reader that needs them without a defaults tree.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace sl::cli {

class Config {
 public:
  explicit Config(nlohmann::json defaults);

  void merge_file(const std::string& path);                 // errors name the file; follows "extends"
  void merge(const nlohmann::json& overrides, const std::string& origin);
  void set(const std::string& assignment);                  // "a.b.c=value"

  const nlohmann::json& tree() const { return value_; }
  const nlohmann::json& at(const std::string& path) const;  // "a.b.c"
  double number(const std::string& path) const;
  int64_t integer(const std::string& path) const;
  bool boolean(const std::string& path) const;
  std::string string(const std::string& path) const;
  std::vector<double> numbers(const std::string& path) const;

 private:
  nlohmann::json defaults_;
  nlohmann::json value_;
};

// One file of an "extends" chain: its path as reached and its JSON, without the "extends" key.
struct ConfigFile {
  std::string path;
  nlohmann::json content;
};

// The files that the config file at `path` stands for, its bases first and `path` last, in the
// order merge_file() merges them. Errors name the file, as merge_file()'s do (unreadable, not
// JSON, a bad "extends", a missing base, a cycle, more than 16 levels).
std::vector<ConfigFile> read_config_chain(const std::string& path);

// Every key path of a JSON object ("a", "a.b", ...), for suggestions and documentation.
std::vector<std::string> key_paths(const nlohmann::json& j, const std::string& prefix = "");
// The candidate closest to `key` by edit distance ("" when none is reasonably close).
std::string nearest(const std::string& key, const std::vector<std::string>& candidates);

}  // namespace sl::cli
