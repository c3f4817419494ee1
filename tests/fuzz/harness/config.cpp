// Harness: training configs, tools/common/config.h validated against train/train_config.h's
// defaults. The input up to its first NUL byte is the config file; each further NUL-separated
// piece is one --set assignment. Then check_train_config, sky_options, predictor_options and
// vsg_grid read the merged tree, as the train executable does before it builds a stage.
// Invariant: the merged tree still has every default key with the default's JSON type.
#include <cstring>

#include "tests/fuzz/harness/fuzz_harness.h"
#include "tools/common/config.h"
#include "train/train_config.h"

namespace sl::test {

namespace {
using nlohmann::json;

// The type rules of tools/common/config.h: integers may stand for floats, null for strings.
bool same_kind(const json& def, const json& val) {
  if (def.is_null()) return true;
  if (def.is_number_float()) return val.is_number();
  if (def.is_number_integer()) return val.is_number_integer();
  if (def.is_string()) return val.is_string() || val.is_null();
  return def.type() == val.type();
}

void check_types(const json& defaults, const json& value, const std::string& path) {
  if (!defaults.is_object() || defaults.empty()) {
    if (!same_kind(defaults, value)) violation("config", "key '" + path + "' changed type to " + value.type_name());
    return;
  }
  if (!value.is_object()) violation("config", "key '" + path + "' is no longer an object");
  for (auto it = defaults.begin(); it != defaults.end(); ++it) {
    if (!value.contains(it.key())) violation("config", "key '" + path + "." + it.key() + "' disappeared");
    check_types(*it, value.at(it.key()), path + "." + it.key());
  }
}
}  // namespace

void fuzz_config(const uint8_t* data, size_t size) {
  const char* target = "config";
  const uint8_t* end = data + size;
  const uint8_t* nul = static_cast<const uint8_t*>(std::memchr(data, 0, size));
  const std::string path = write_scratch("config.json", data, static_cast<size_t>((nul ? nul : end) - data));
  static const json defaults = train::default_train_config();
  refuses_cleanly_or_runs(target, [&] {
    cli::Config config(defaults);
    config.merge_file(path);
    for (const uint8_t* p = nul; p && p < end;) {
      const uint8_t* next = static_cast<const uint8_t*>(std::memchr(p + 1, 0, static_cast<size_t>(end - p - 1)));
      config.set(std::string(reinterpret_cast<const char*>(p + 1), static_cast<size_t>((next ? next : end) - p - 1)));
      p = next;
    }
    check_types(defaults, config.tree(), "");
    train::check_train_config(config.tree());
    train::sky_options(config.tree());
    train::predictor_options(config.tree());
    train::vsg_grid(config.tree(), 1.65);
  });
}

}  // namespace sl::test
