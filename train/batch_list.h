// The JSON list of `streetlight-insert --batch LIST.json` (factored out of tools/insert.cpp so
// that it can be fuzzed, tests/fuzz): [{"image": P, "intrinsics": P, "depth": P, "lidar": P,
// "calib": P}, ...] with every key but "image" optional; relative paths are relative to the
// list's folder.
// Contract: read_batch_list() returns one PhotoSources per entry (paths resolved, other fields
// at their defaults) in file order. It checks only the list, not the files it names. Throws
// ONE sl::Error naming the list for: an unreadable file, invalid JSON, a top level that is not
// an array, an entry that is not an object, a listed key whose value is not a string, an entry
// without "image", and an empty list.
#pragma once
#include <string>
#include <vector>

#include "train/photo_input.h"

namespace sl::train {

std::vector<PhotoSources> read_batch_list(const std::string& path);

}  // namespace sl::train
