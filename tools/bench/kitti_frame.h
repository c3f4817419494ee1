// The shared KITTI frame the benchmarks run on: ../shared/data/street/kitti_000008 (MANIFEST.md)
// holds 000008.png, 000008.txt (P2), 000008_calib.json and 000008_velodyne.bin. kitti_000008(dir)
// names those files as a train::PhotoSources (lidar depth); load_photo() reads and checks them.
#pragma once
#include <string>

#include "train/photo_input.h"

namespace sl::bench {

inline train::PhotoSources kitti_000008(const std::string& dir) {
  train::PhotoSources src;
  src.image = dir + "/000008.png";
  src.intrinsics = dir + "/000008.txt";
  src.calib = dir + "/000008_calib.json";
  src.lidar = dir + "/000008_velodyne.bin";
  return src;
}

}  // namespace sl::bench
