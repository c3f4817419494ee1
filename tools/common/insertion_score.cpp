#include "tools/common/insertion_score.h"

#include <algorithm>
#include <cmath>

#include "data/panorama.h"
#include "train/metrics.h"
#include "util/math.h"

namespace sl::cli {

using data::StreetView;
using data::to_ldr;
using nlohmann::json;
using render::Placement;
using train::masked_psnr;
using train::mean_of;
using train::PhotoInsertion;
using train::PsnrScores;

InsertionScore score_insertion(const train::EstimatedLighting& l, const data::StreetSample& s, const render::Mesh& mesh,
                               const train::PhotoInsertionOptions& o) {
  const StreetView& v = s.views[0];
  Placement pose{s.object_x, s.object_z, s.object_yaw_deg, s.object_scale};
  const Tensor with = to_ldr(s.insert_with_object_hdr.contiguous(), s.exposure);
  const Tensor without = to_ldr(s.insert_without_object_hdr.defined() ? s.insert_without_object_hdr.contiguous()
                                                                      : v.hdr.contiguous(), s.exposure);
  // The photo we insert into is the truth's own "without" image: the same render as view 0
  // normally, and its cleaner re-render with datagen insertion.spp, whose noise would otherwise
  // count as our error in every background pixel of the region.
  const PhotoInsertion ins = insert_into_photo(l, without, v.depth, v.camera, mesh, pose, o);
  const Tensor gm = s.insert_object_mask.contiguous(), sm = ins.shadow_map.contiguous();
  const int64_t n = with.size(1) * with.size(2);
  const float *wp = with.data<float>(), *np = without.data<float>(), *mp = gm.data<float>(), *sp = sm.data<float>();
  std::vector<char> region(n, 0);
  double ratio_err = 0;
  int64_t ratio_n = 0;
  for (int64_t i = 0; i < n; ++i) {
    double lw = 0, ln = 0;
    for (int c = 0; c < 3; ++c) lw += ldr_decode(wp[c * n + i]), ln += ldr_decode(np[c * n + i]);
    const double true_ratio = ln > 1e-6 ? std::min(lw / ln, 1.5) : 1.0;
    const bool object = mp[i] > 0.5 / 255.0;
    const bool shadow = !object && std::abs(true_ratio - 1.0) > 0.02;
    region[i] = object || shadow || sp[i] < 0.98;
    if (region[i] && !object) ratio_err += std::abs(static_cast<double>(sp[i]) - true_ratio), ++ratio_n;
  }
  InsertionScore r;
  const PsnrScores p = masked_psnr(ins.composite_ldr, with, region);
  r.valid = p.valid;
  r.psnr = p.psnr;
  std::vector<char> object(n, 0), edge(n, 0), shadow(n, 0);
  for (int64_t i = 0; i < n; ++i) {
    object[i] = mp[i] >= 0.98f;
    edge[i] = mp[i] > 0.5f / 255.0f && mp[i] < 0.98f;
    shadow[i] = region[i] && !object[i] && !edge[i];
  }
  auto part = [&](const std::vector<char>& m) {
    const PsnrScores q = masked_psnr(ins.composite_ldr, with, m);
    return q.valid ? q.psnr : std::nan("");
  };
  r.psnr_object = part(object), r.psnr_edge = part(edge), r.psnr_shadow = part(shadow);
  r.shadow_ratio_error = ratio_n ? ratio_err / ratio_n : 0.0;
  r.ms = ins.render_ms;
  return r;
}

void PartScores::add(const InsertionScore& s) {
  if (std::isfinite(s.psnr_object)) object.push_back(s.psnr_object);
  if (std::isfinite(s.psnr_edge)) edge.push_back(s.psnr_edge);
  if (std::isfinite(s.psnr_shadow)) shadow.push_back(s.psnr_shadow);
}

json PartScores::to_json() const {
  json j = json::object();
  if (!object.empty()) j["object"] = mean_of(object);
  if (!edge.empty()) j["edge"] = mean_of(edge);
  if (!shadow.empty()) j["shadow"] = mean_of(shadow);
  return j;
}

}  // namespace sl::cli
