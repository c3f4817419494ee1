// The insertion score of Sec 4.3 against a generated street's path-traced truth: the sample's
// object is inserted with the estimated lighting into the truth's own "without" image, and the
// composite is compared with the truth's "with" image over the object ∪ shadow region (PSNR, and
// per part: object interior, object edge, shadow), with the mean absolute error of the shadow
// ratio S on the region's background pixels.
//
// Contract: the sample carries the insertion pair (datagen insertion.enabled); the region is the
// truth's object mask ∪ the pixels the truth darkens or brightens by more than 2% ∪ the pixels the
// estimate shadows below 0.98. A part with no pixel scores NaN; valid = false when the region is
// empty.
#pragma once
#include <vector>

#include <nlohmann/json.hpp>

#include "data/street_dataset.h"
#include "render/mesh.h"
#include "train/inference.h"
#include "train/photo_insertion.h"

namespace sl::cli {

struct InsertionScore {
  double psnr = 0, shadow_ratio_error = 0, ms = 0;
  // The region's parts: object interior (coverage ≥ 0.98 in the truth), object edge (0 < coverage
  // < 0.98) and shadow (the rest of the region); NaN where a part is empty.
  double psnr_object = 0, psnr_edge = 0, psnr_shadow = 0;
  bool valid = false;
};

InsertionScore score_insertion(const train::EstimatedLighting& l, const data::StreetSample& s, const render::Mesh& mesh,
                               const train::PhotoInsertionOptions& o);

// Mean PSNR of each region part over the samples where the part is not empty.
struct PartScores {
  std::vector<double> object, edge, shadow;
  void add(const InsertionScore& s);
  nlohmann::json to_json() const;
};

}  // namespace sl::cli
