// Grain sizes for nn's parallel loops (internal).
//
// Contract: grain_for(work_per_item) is the number of loop items per parallel chunk such that a
// chunk holds at least ~64 K units of work (multiply-adds or elements touched). Small problems
// thus run on the calling thread: waking a second thread costs more than they do, and on a
// loaded machine a parallel region can wait milliseconds for a descheduled thread (gradchecks
// run thousands of tiny ops). Chunking never changes results: every item is computed by one
// call of the loop body whatever the chunk, so outputs are bitwise the same (parallel.h).
#pragma once
#include <algorithm>
#include <cstdint>

namespace sl::nn::detail {

inline int64_t grain_for(int64_t work_per_item) {
  constexpr int64_t kMinWorkPerChunk = int64_t{1} << 16;
  return std::max<int64_t>(1, kMinWorkPerChunk / std::max<int64_t>(work_per_item, 1));
}

}  // namespace sl::nn::detail
