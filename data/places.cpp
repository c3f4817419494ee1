// Places of LDR panoramas and place-balanced weights. See places.h.
#include "data/places.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "data/csv.h"
#include "util/error.h"

namespace sl::data {

std::string Places::place_of(const std::string& file) const {
  const auto it = place.find(file);
  if (it != place.end()) return it->second;
  const size_t first = file.find("__");
  if (first == std::string::npos) return file;
  const size_t second = file.find("__", first + 2);
  return second == std::string::npos ? file : file.substr(0, second);
}

Places read_places(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  SL_CHECK(in.good(), "places '", path, "' cannot be opened");
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::vector<CsvRecord> recs = parse_csv(ss.str(), "places", path);
  SL_CHECK(!recs.empty(), "places '", path, ":1': the file is empty (expected the header file,place)");
  const CsvRecord& header = recs[0];
  size_t file_col = header.fields.size(), place_col = header.fields.size();
  for (size_t i = 0; i < header.fields.size(); ++i) {
    if (header.fields[i] == "file") file_col = i;
    if (header.fields[i] == "place") place_col = i;
  }
  SL_CHECK(file_col < header.fields.size() && place_col < header.fields.size(), "places '", path, ":", header.line,
           "': the header needs the columns file and place");
  Places out;
  out.path = path;
  for (size_t r = 1; r < recs.size(); ++r) {
    const CsvRecord& rec = recs[r];
    SL_CHECK(rec.fields.size() == header.fields.size(), "places '", path, ":", rec.line, "': ", rec.fields.size(),
             " fields, the header has ", header.fields.size(), " (a field holding commas must be quoted)");
    const std::string& file = rec.fields[file_col];
    const std::string& where = rec.fields[place_col];
    SL_CHECK(!file.empty() && !where.empty(), "places '", path, ":", rec.line, "': empty file name or place");
    SL_CHECK(out.place.emplace(file, where).second, "places '", path, ":", rec.line, "': '", file, "' is named twice");
  }
  return out;
}

std::vector<double> place_balanced_weights(const std::vector<std::string>& places, double exponent) {
  SL_CHECK(!places.empty(), "place_balanced_weights: no panoramas");
  SL_CHECK(std::isfinite(exponent) && exponent >= 0.0 && exponent <= 1.0,
           "place_balanced_weights: the exponent must lie in [0, 1], got ", exponent);
  std::map<std::string, double> size;
  for (const auto& p : places) size[p] += 1.0;
  double total = 0.0;
  for (const auto& [p, m] : size) total += std::pow(m, exponent);
  std::vector<double> w(places.size());
  for (size_t i = 0; i < places.size(); ++i) {
    const double m = size.at(places[i]);
    w[i] = std::pow(m, exponent) / (m * total);
  }
  return w;
}

size_t pick_weighted(const std::vector<double>& cumulative, double u) {
  SL_CHECK(!cumulative.empty(), "pick_weighted: an empty table");
  const auto it = std::upper_bound(cumulative.begin(), cumulative.end(), u);
  return std::min(static_cast<size_t>(it - cumulative.begin()), cumulative.size() - 1);
}

}  // namespace sl::data
