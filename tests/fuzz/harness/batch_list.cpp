// Harness: train/batch_list.h read_batch_list (streetlight-insert --batch LIST.json).
// Invariant: at least one entry, each with an image path.
#include "tests/fuzz/harness/fuzz_harness.h"
#include "train/batch_list.h"

namespace sl::fuzz {

void fuzz_batch_list(const uint8_t* data, size_t size) {
  const std::string path = write_scratch("list.json", data, size);
  refuses_cleanly_or_runs("batch_list", [&] {
    const std::vector<train::PhotoSources> list = train::read_batch_list(path);
    if (list.empty()) violation("batch_list", "empty list accepted");
    for (const auto& s : list)
      if (s.image.empty()) violation("batch_list", "entry without an image accepted");
  });
}

}  // namespace sl::fuzz
