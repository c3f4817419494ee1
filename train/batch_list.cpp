#include "train/batch_list.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "util/error.h"

namespace sl::train {

namespace fs = std::filesystem;
using nlohmann::json;

std::vector<BatchListEntry> read_batch_list(const std::string& path) {
  std::ifstream f(path);
  SL_CHECK(f.good(), "--batch '", path, "' is neither a folder nor a readable JSON list");
  json j;
  try {
    j = json::parse(f);
  } catch (const std::exception& e) {
    fail("--batch '", path, "' is not valid JSON: ", e.what());
  }
  SL_CHECK(j.is_array(), "--batch '", path, "' must hold a JSON array of {image, intrinsics, ...}");
  const fs::path root = fs::path(path).parent_path();
  std::vector<BatchListEntry> out;
  for (size_t i = 0; i < j.size(); ++i) {
    const json& e = j[i];
    SL_CHECK(e.is_object(), "--batch '", path, "': entry ", i, " must be an object {image, intrinsics, ...}, got ",
             e.type_name());
    auto rel = [&](const char* k) {
      if (!e.contains(k)) return std::string();
      SL_CHECK(e.at(k).is_string(), "--batch '", path, "': entry ", i, " key \"", k, "\" must be a path string, got ",
               e.at(k).type_name());
      const fs::path p(e.at(k).get<std::string>());
      return (p.is_absolute() ? p : root / p).string();
    };
    PhotoSources s;
    s.image = rel("image");
    s.intrinsics = rel("intrinsics");
    s.depth = rel("depth");
    s.lidar = rel("lidar");
    s.calib = rel("calib");
    SL_CHECK(!s.image.empty(), "--batch '", path, "': an entry has no \"image\"");
    if (e.contains("fov")) {
      SL_CHECK(e.at("fov").is_number(), "--batch '", path, "': entry ", i, " key \"fov\" must be a number of degrees, got ",
               e.at("fov").type_name());
      s.fov_deg = e.at("fov").get<double>();
      SL_CHECK(std::isfinite(s.fov_deg) && s.fov_deg > 0.0 && s.fov_deg < 180.0, "--batch '", path, "': entry ", i,
               " \"fov\" must lie between 0 and 180 degrees, got ", s.fov_deg);
    }
    BatchListEntry entry;
    entry.sources = s;
    entry.labels = rel("labels");
    char index_id[32];
    std::snprintf(index_id, sizeof index_id, "%06zu", i);
    entry.id = index_id;
    if (e.contains("id")) {
      SL_CHECK(e.at("id").is_string(), "--batch '", path, "': entry ", i, " key \"id\" must be a string, got ",
               e.at("id").type_name());
      entry.id = e.at("id").get<std::string>();
      SL_CHECK(!entry.id.empty() && entry.id != "." && entry.id != ".." && entry.id.find('/') == std::string::npos &&
                   entry.id.find('\\') == std::string::npos,
               "--batch '", path, "': entry ", i, " id '", entry.id, "' is not a plain file name");
    }
    out.push_back(entry);
  }
  SL_CHECK(!out.empty(), "--batch '", path, "' lists no images");
  return out;
}

}  // namespace sl::train
