// Sun labels of LDR panoramas. See sun_labels.h.
#include "data/sun_labels.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "data/csv.h"
#include "render/equirect.h"
#include "util/error.h"

namespace sl::data {

namespace {

// A value as shown in a message: on one line (a quoted field may hold line breaks).
std::string shown(std::string v) {
  for (char& c : v)
    if (c == '\n' || c == '\r') c = ' ';
  return v;
}

std::string allowed(const std::map<std::string, int>& m) {
  std::string s;
  for (const auto& [k, v] : m) s += (s.empty() ? "" : ", ") + k;
  return s;
}

template <class E>
E parse_enum(const std::string& value, const std::map<std::string, int>& names, const char* column,
             const std::string& where) {
  const auto it = names.find(value);
  SL_CHECK(it != names.end(), "sun labels '", where, "': unknown ", column, " '", shown(value), "' (expected one of ",
           allowed(names), ")");
  return static_cast<E>(it->second);
}

bool parse_number(const std::string& s, double* out) {
  if (s.empty()) return false;
  char* end = nullptr;
  *out = std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size() && std::isfinite(*out);
}

}  // namespace

const char* to_string(SunVisibility v) {
  switch (v) {
    case SunVisibility::Visible: return "visible";
    case SunVisibility::Occluded: return "occluded";
    case SunVisibility::None: return "none";
  }
  return "?";
}
const char* to_string(LabelConfidence c) {
  switch (c) {
    case LabelConfidence::High: return "high";
    case LabelConfidence::Medium: return "medium";
    case LabelConfidence::Low: return "low";
  }
  return "?";
}
const char* to_string(SceneKind s) { return s == SceneKind::Street ? "street" : "other"; }

SunLabels read_sun_labels(const std::string& path, int frame_width, int frame_height) {
  SL_CHECK(frame_width > 0 && frame_height > 0, "sun labels '", path, "': label frame must be positive, got ",
           frame_width, "x", frame_height);
  std::ifstream in(path, std::ios::binary);
  SL_CHECK(in.good(), "sun labels '", path, "' cannot be opened");
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::vector<CsvRecord> recs = parse_csv(ss.str(), "sun labels", path);
  SL_CHECK(!recs.empty(), "sun labels '", path, ":1': the file is empty (expected the header ",
           "file,sun,u,v,confidence,scene,note)");
  const CsvRecord& header = recs[0];
  std::map<std::string, size_t> col;
  for (size_t i = 0; i < header.fields.size(); ++i) col.emplace(header.fields[i], i);
  for (const char* need : {"file", "sun", "u", "v", "confidence", "scene"})
    SL_CHECK(col.count(need), "sun labels '", path, ":", header.line, "': the header has no column '", need,
             "' (expected file,sun,u,v,confidence,scene,note)");
  static const std::map<std::string, int> kSun = {{"visible", int(SunVisibility::Visible)},
                                                  {"occluded", int(SunVisibility::Occluded)},
                                                  {"none", int(SunVisibility::None)}};
  static const std::map<std::string, int> kConf = {{"high", int(LabelConfidence::High)},
                                                   {"medium", int(LabelConfidence::Medium)},
                                                   {"low", int(LabelConfidence::Low)}};
  static const std::map<std::string, int> kScene = {{"street", int(SceneKind::Street)},
                                                    {"other", int(SceneKind::Other)}};
  SunLabels out;
  out.path = path;
  out.frame_width = frame_width;
  out.frame_height = frame_height;
  std::set<std::string> seen;
  for (size_t r = 1; r < recs.size(); ++r) {
    const CsvRecord& rec = recs[r];
    const std::string where = cat(path, ":", rec.line);
    if (rec.fields.size() < header.fields.size())
      fail("sun labels '", where, "': missing column '", header.fields[rec.fields.size()], "' (", rec.fields.size(),
           " fields, the header has ", header.fields.size(), ")");
    SL_CHECK(rec.fields.size() == header.fields.size(), "sun labels '", where, "': ", rec.fields.size(),
             " fields, the header has ", header.fields.size(), " (a field holding commas must be quoted)");
    auto get = [&](const char* name) -> const std::string& { return rec.fields[col.at(name)]; };
    PanoramaSunLabel l;
    l.line = rec.line;
    l.file = get("file");
    SL_CHECK(!l.file.empty(), "sun labels '", where, "': empty file name");
    SL_CHECK(seen.insert(l.file).second, "sun labels '", where, "': '", shown(l.file), "' is labelled twice");
    l.sun = parse_enum<SunVisibility>(get("sun"), kSun, "sun", where);
    l.confidence = parse_enum<LabelConfidence>(get("confidence"), kConf, "confidence", where);
    l.scene = parse_enum<SceneKind>(get("scene"), kScene, "scene", where);
    if (col.count("note")) l.note = get("note");
    const std::string &us = get("u"), &vs = get("v");
    if (!us.empty() || !vs.empty()) {
      SL_CHECK(!us.empty() && !vs.empty(), "sun labels '", where, "': give both u and v or neither (u '", shown(us),
               "', v '", shown(vs), "')");
      SL_CHECK(parse_number(us, &l.u), "sun labels '", where, "': u '", shown(us), "' is not a number");
      SL_CHECK(parse_number(vs, &l.v), "sun labels '", where, "': v '", shown(vs), "' is not a number");
      SL_CHECK(l.u >= 0.0 && l.u <= frame_width && l.v >= 0.0 && l.v <= frame_height, "sun labels '", where,
               "': (u, v) = (", us, ", ", vs, ") lies outside the ", frame_width, "x", frame_height, " image");
      l.has_position = true;
    }
    SL_CHECK(l.has_position || l.sun != SunVisibility::Visible, "sun labels '", where, "': a visible sun needs u and v");
    SL_CHECK(!l.has_position || l.sun != SunVisibility::None, "sun labels '", where,
             "': a 'none' label has no sun position, but u and v are given");
    out.rows.push_back(std::move(l));
  }
  SL_CHECK(!out.rows.empty(), "sun labels '", path, "': no rows after the header");
  return out;
}

const PanoramaSunLabel* SunLabels::find(const std::string& file) const {
  for (const auto& r : rows)
    if (r.file == file) return &r;
  return nullptr;
}

glm::dvec2 SunLabels::pixel_in(const PanoramaSunLabel& l, int width, int height) const {
  return {l.u * width / frame_width, l.v * height / frame_height};
}

glm::dvec3 SunLabels::direction(const PanoramaSunLabel& l, int width, int height) const {
  SL_CHECK(l.has_position, "sun labels '", path, ":", l.line, "': '", l.file, "' (", to_string(l.sun),
           ") has no sun position");
  SL_CHECK(width > 0 && height > 0, "sun labels '", path, "': image size must be positive, got ", width, "x", height);
  const glm::dvec2 p = pixel_in(l, width, height);
  const auto d = render::equirect::uv_to_direction(p.x, p.y, width, height);
  return glm::normalize(glm::dvec3(d.x, d.y, d.z));
}

}  // namespace sl::data
