// Where each LDR panorama was taken (../shared/data/pano_ldr/places.csv, MANIFEST.md there), and
// sampling weights that balance places against each other.
//
// Contract:
// - read_places(path): a CSV (data/csv.h) with the columns file and place (any order, extra
//   columns ignored). Throws sl::Error "places 'PATH:LINE': ..." for a file that cannot be
//   opened, a header without file or place, a row whose field count differs from the header's,
//   an empty file name or place, or a file named twice.
// - Places::place_of(file): the file's place; for a file the table does not name (the first 69
//   panoramas of the folder predate places.csv), the repository its name starts with
//   ("owner__repository__name" gives "owner__repository"), else the name itself. That is the
//   split's grouping of those 69 (configs/pano_ldr_split_69.json) for all but the few
//   repositories MANIFEST.md says hold several places, which it merges.
// - place_balanced_weights(places, exponent): one weight per entry of `places` (a place per
//   panorama), summing to 1, such that a place with m panoramas receives a share proportional to
//   m^exponent, split evenly among its panoramas. exponent 1: every panorama alike (the places
//   in proportion to their size); 0: every place alike; between: a compromise (0.5: the square
//   root of the size). Requires exponent in [0, 1] and a non-empty list.
// - pick_weighted(cumulative, u): the index i with cumulative[i-1] <= u < cumulative[i] for
//   u in [0, 1) and a non-decreasing cumulative sum ending at 1 (the last index for u at or past
//   the end, so rounding never leaves the table).
#pragma once
#include <map>
#include <string>
#include <vector>

namespace sl::data {

struct Places {
  std::string path;                          // the CSV it was read from ("" when none)
  std::map<std::string, std::string> place;  // file name -> place
  std::string place_of(const std::string& file) const;
};

Places read_places(const std::string& path);

std::vector<double> place_balanced_weights(const std::vector<std::string>& places, double exponent);
size_t pick_weighted(const std::vector<double>& cumulative, double u);

}  // namespace sl::data
