// streetlight.Lighting as the insertion binding sees it (python/lighting.cpp binds it): one
// estimate of train/inference.h with what made it, so insert(..., sun_from_shadows=True) and
// Lighting.with_sun() can estimate again exactly as streetlight-insert does.
#pragma once
#include <memory>
#include <optional>
#include <string>

#include "data/sun_from_shadows.h"
#include "train/inference.h"

namespace sl::python {

struct PyLighting {
  std::shared_ptr<train::LightingEstimator> estimator;
  train::InferenceView view;  // the photo it was estimated from (LDR, depth, camera)
  train::SunEdit edit;        // the caller's sun edit
  train::EstimatedLighting lighting;
  std::optional<data::ShadowSunFit> shadow_fit;  // set when the sun came from the photo's shadows
  double shadow_intensity_scale = 1.0;
};

}  // namespace sl::python
