// Where the tools and the Python module find the released weights when no checkpoint is given.
//
// Contract:
// - released_model_path(): the lighting model (models/streetlight.safetensors). The first of:
//   1. $STREETLIGHT_MODEL (it must name a file: a set but wrong variable is an error, not a
//      silent fallback);
//   2. models/streetlight.safetensors in the working directory (a clone of the repository);
//   3. an installed copy: share/streetlight/models/ (CMAKE_INSTALL_DATADIR) under the prefix of
//      the running program or module. The prefix is found from the file the code runs from (the
//      executable, or the Python extension) by looking for that folder in each of its three
//      nearest parent folders: prefix/bin/streetlight-insert and
//      prefix/lib/python3.X/dist-packages/streetlight.so both find prefix/share/streetlight, so an
//      installed tree works from anywhere and after it is moved;
//   4. models/ in the source tree the code was built from.
//   Throws sl::Error listing every place it looked when none holds the file.
// - released_sun_glare_path(): the learned sun-glare detector (models/sun_glare.safetensors,
//   train/sun_glare.h), looked up the same way with $STREETLIGHT_SUN_GLARE; "" when there is none
//   (the detector is optional).
// - installed_models_dir(): the folder of step 3, or "" when the running code is not installed.
#pragma once
#include <string>

namespace sl::cli {

std::string released_model_path();
std::string released_sun_glare_path();
std::string installed_models_dir();

}  // namespace sl::cli
