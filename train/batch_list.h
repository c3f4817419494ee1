// The JSON list of `streetlight-insert --batch LIST.json` (factored out of tools/insert.cpp so
// that it can be fuzzed, tests/fuzz): [{"image": P, "intrinsics": P, "depth": P, "lidar": P,
// "calib": P, "fov": DEG, "labels": P, "id": NAME}, ...] with every key but "image" optional
// ("fov": the horizontal field of view when there is no "intrinsics"; without either, the
// image's EXIF focal length, train/photo_input.h); relative
// paths are relative to the list's folder. "labels" is the frame's KITTI label_2 file, carried
// into the augmented output; "id" names the output frame (default: the entry's index, 6 digits).
// Contract: read_batch_list() returns one entry per list item (paths resolved, other fields
// at their defaults) in file order. It checks only the list, not the files it names. Throws
// ONE sl::Error naming the list for: an unreadable file, invalid JSON, a top level that is not
// an array, an entry that is not an object, a listed key whose value is not a string (a "fov"
// that is not a number in (0, 180)), an entry
// without "image", an id that is empty or not a plain file name, and an empty list.
#pragma once
#include <string>
#include <vector>

#include "train/photo_input.h"

namespace sl::train {

struct BatchListEntry {
  PhotoSources sources;
  std::string id;      // output frame id
  std::string labels;  // KITTI label_2 file of the input frame, or empty
};

std::vector<BatchListEntry> read_batch_list(const std::string& path);

}  // namespace sl::train
