#include "data/hdri_split.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>

#include <nlohmann/json.hpp>

#include "util/error.h"

namespace sl::data {

namespace fs = std::filesystem;

HdriSplit read_hdri_split(const std::string& path) {
  std::ifstream in(path);
  SL_CHECK(in.good(), "HDRI split file '", path, "' cannot be opened");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const std::exception& e) {
    SL_CHECK(false, "HDRI split file '", path, "' is not valid JSON: ", e.what());
  }
  SL_CHECK(j.is_object(), "HDRI split file '", path, "': expected a JSON object of split name -> list of files");
  HdriSplit s;
  s.file = path;
  std::set<std::string> seen;
  for (const auto& [key, value] : j.items()) {
    if (value.is_string()) continue;  // "comment" and similar notes
    SL_CHECK(value.is_array(), "HDRI split file '", path, "': key '", key, "' must be a list of file names");
    auto& names = s.splits[key];
    for (const auto& v : value) {
      SL_CHECK(v.is_string(), "HDRI split file '", path, "': key '", key, "' holds a non-string entry ", v.dump());
      const std::string name = v.get<std::string>();
      SL_CHECK(seen.insert(name).second, "HDRI split file '", path, "': '", name,
               "' is listed twice (splits must be disjoint)");
      names.push_back(name);
    }
  }
  SL_CHECK(!s.splits.empty(), "HDRI split file '", path, "' lists no split");
  return s;
}

std::vector<std::string> HdriSplit::split_names(const std::string& split) const {
  std::vector<std::string> out;
  std::set<std::string> parts;
  size_t begin = 0;
  while (true) {
    const size_t end = split.find('+', begin);
    const std::string part = split.substr(begin, end == std::string::npos ? std::string::npos : end - begin);
    SL_CHECK(!part.empty(), "HDRI split file '", file, "': split '", split, "' has an empty part");
    SL_CHECK(parts.insert(part).second, "HDRI split file '", file, "': split '", split, "' names '", part, "' twice");
    const auto it = splits.find(part);
    SL_CHECK(it != splits.end(), "HDRI split file '", file, "' has no split '", part, "'");
    out.insert(out.end(), it->second.begin(), it->second.end());
    if (end == std::string::npos) break;
    begin = end + 1;
  }
  return out;
}

std::vector<std::string> HdriSplit::split_paths(const std::string& folder, const std::string& split) const {
  std::vector<std::string> out;
  for (const auto& name : split_names(split)) {
    const fs::path p = fs::path(folder) / name;
    std::error_code ec;
    SL_CHECK(fs::is_regular_file(p, ec), "HDRI split file '", file, "' names '", name, "' (split '", split,
             "'), which is missing from '", folder, "'");
    out.push_back(p.string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace sl::data
