// make_norm: the normalisation module a block asks for by name.
//
// Contract: make_norm(kind, channels, spatial_dims, groups): "batch" (BatchNorm1d/2d/3d by
// spatial_dims), "group", "instance" (affine, as generators usually use it) or "none"
// (Identity). For "group" the group count is the largest divisor of `channels` not above
// `groups`, so any width works. Unknown kinds throw naming the kind.
#pragma once
#include <memory>
#include <string>

#include "nn/module.h"
#include "nn/modules/batch_norm.h"
#include "nn/modules/group_norm.h"
#include "nn/modules/instance_norm.h"

namespace sl::nn {

std::shared_ptr<Module> make_norm(const std::string& kind, int64_t channels, int spatial_dims, int64_t groups = 8);

}  // namespace sl::nn
