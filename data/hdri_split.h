// A scene-disjoint split of a folder of real HDR panoramas into train / val / test, read from a
// JSON file (configs/hdri_split.json): {"train": [names], "val": [names], "test": [names]} plus
// optional string keys such as "comment". Names are file names inside the panorama folder.
//
// Requires: every split lists distinct names; no name appears in two splits.
// Guarantees: split_paths returns the listed files of one split as full paths in the folder, in
//   byte-wise sorted order, after checking that each exists. A split name may join several with
//   '+' ("train+val": a final model trained on the validation places too, once its recipe is
//   fixed); split_names returns the names of each part in turn, in file order.
// Throws: sl::Error naming the split file and the key (not JSON, a split that is not a list of
//   strings, a name listed twice or in two splits, a split that does not exist, an empty part or
//   one part named twice in a union), or naming the missing panorama, the folder and the split file.
#pragma once
#include <map>
#include <string>
#include <vector>

namespace sl::data {

struct HdriSplit {
  std::string file;  // the JSON file it was read from
  std::map<std::string, std::vector<std::string>> splits;

  bool has(const std::string& split) const { return splits.count(split) > 0; }
  // The names listed under `split` (or under each part of "a+b", in turn), in file order.
  std::vector<std::string> split_names(const std::string& split) const;
  // Full paths of `split`'s panoramas in `folder` (throws naming a missing file or split).
  std::vector<std::string> split_paths(const std::string& folder, const std::string& split) const;
};

HdriSplit read_hdri_split(const std::string& path);

}  // namespace sl::data
