#include "nn/modules/norm.h"

#include "autodiff/tape.h"
#include "nn/functional/normalization.h"
#include "nn/modules/activations.h"

namespace sl::nn {

std::shared_ptr<Module> make_norm(const std::string& kind, int64_t channels, int spatial_dims, int64_t groups) {
  SL_CHECK(spatial_dims >= 1 && spatial_dims <= 3, "make_norm: spatial_dims must be 1, 2 or 3, got ", spatial_dims);
  if (kind == "batch") {
    if (spatial_dims == 1) return std::make_shared<BatchNorm1d>(channels);
    if (spatial_dims == 2) return std::make_shared<BatchNorm2d>(channels);
    return std::make_shared<BatchNorm3d>(channels);
  }
  if (kind == "group") {
    SL_CHECK(groups >= 1, "make_norm: groups must be >= 1, got ", groups);
    int64_t g = std::min(groups, channels);
    while (channels % g != 0) --g;
    return std::make_shared<GroupNorm>(g, channels);
  }
  if (kind == "instance") return std::make_shared<InstanceNorm>(channels, 1e-5, true);
  if (kind == "none") return std::make_shared<Identity>();
  fail("make_norm: unknown norm '", kind, "' (valid: batch, group, instance, none)");
}

}  // namespace sl::nn
