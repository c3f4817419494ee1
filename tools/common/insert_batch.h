// streetlight-insert --batch (Sec 4.4 augmentation): random objects inserted into many photos,
// written as an augmented dataset in KITTI layout. Inputs: a KITTI-layout folder (image_2/<id>.png
// with calib/<id>.txt, optional label_2/<id>.txt, velodyne/<id>.bin for depth, or depth/<id>.png)
// or a LIST.json of {image, intrinsics, depth?, lidar?, calib?, labels?, id?} (e.g. nuScenes front
// cameras with a per-image intrinsics JSON). Output: a KITTI-layout folder with the same ids,
// written in place frame by frame so that a killed run resumes (batch.json marks the folder; a
// frame is finished when its image exists, written last; leftovers of a killed run are swept).
// Throws: sl::Error naming the flag, the file or the frame (exit 2 through cli::run_main).
#pragma once
#include "tools/common/cli.h"

namespace sl::cli {

// The whole batch mode from streetlight-insert's parsed flags (--batch, --out, --object, ...);
// returns the exit code.
int insert_batch(const Args& a);

}  // namespace sl::cli
