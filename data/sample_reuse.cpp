// Reusing the samples of an earlier street-dataset render. See sample_reuse.h.
#include "data/sample_reuse.h"

#include <algorithm>
#include <filesystem>

#include "data/street_dataset.h"
#include "util/error.h"
#include "util/file.h"

namespace sl::data {

namespace fs = std::filesystem;

void check_reusable(const std::string& source_dir, const nlohmann::json& config_tree) {
  const fs::path index = fs::path(source_dir) / "index.json";
  const nlohmann::json j = read_json(index, "--reuse '" + source_dir + "'");
  SL_CHECK(j.is_object() && j.contains("config") && j["config"].is_object(), "--reuse '", source_dir, "': '",
           index.string(), "' has no 'config' object");
  nlohmann::json theirs = j["config"], mine = config_tree;
  theirs.erase("samples");
  mine.erase("samples");
  // RFC 6902: the first operation that turns their config into this one names a differing key.
  // A path spelled two ways (relative here, absolute there) names the same file: not a difference.
  const auto same_file = [&](const nlohmann::json& op) {
    if (op.at("op") != "replace") return false;
    const nlohmann::json::json_pointer at(op.at("path").get<std::string>());
    const nlohmann::json &a = theirs.at(at), &b = mine.at(at);
    std::error_code ec;
    return a.is_string() && b.is_string() && fs::equivalent(a.get<std::string>(), b.get<std::string>(), ec);
  };
  const nlohmann::json patch = nlohmann::json::diff(theirs, mine);
  const auto first = std::find_if_not(patch.begin(), patch.end(), same_file);
  if (first == patch.end()) return;
  const nlohmann::json::json_pointer key(first->at("path").get<std::string>());
  const std::string was = theirs.contains(key) ? theirs.at(key).dump() : "absent";
  const std::string is = mine.contains(key) ? mine.at(key).dump() : "absent";
  std::string name = key.to_string().substr(1);  // "/render/spp" -> "render.spp", as --set spells it
  for (char& ch : name)
    if (ch == '/') ch = '.';
  fail("--reuse '", source_dir, "': its samples were rendered with another config: key '", name, "' is ", was,
       " there and ", is, " here (only 'samples' may differ)");
}

bool reuse_sample(const std::string& source_dir, const std::string& id, const std::string& samples_dir) {
  const fs::path from = fs::path(source_dir) / "samples" / id;
  std::error_code ec;
  if (!fs::is_regular_file(from / "meta.json", ec)) return false;
  AtomicDirectory dir((fs::path(samples_dir) / id).string());
  for (const fs::directory_entry& e : fs::directory_iterator(from)) {
    const fs::path to = dir.file(e.path().filename().string());
    fs::create_hard_link(e.path(), to, ec);
    if (ec) {  // another file system, or one without hard links
      ec.clear();
      fs::copy_file(e.path(), to, ec);
      SL_CHECK(!ec, "cannot copy '", e.path().string(), "' to '", to.string(), "': ", ec.message());
    }
  }
  dir.commit();
  return true;
}

}  // namespace sl::data
