// Harness: train/batch_list.h read_batch_list (streetlight-insert --batch LIST.json).
// Invariant: at least one entry, each with an image path.
#include "tests/fuzz/harness/fuzz_harness.h"
#include "train/batch_list.h"

namespace sl::test {

void fuzz_batch_list(const uint8_t* data, size_t size) {
  const std::string path = write_scratch("list.json", data, size);
  refuses_cleanly_or_runs("batch_list", [&] {
    const std::vector<train::BatchListEntry> list = train::read_batch_list(path);
    if (list.empty()) violation("batch_list", "empty list accepted");
    for (const auto& e : list) {
      if (e.sources.image.empty()) violation("batch_list", "entry without an image accepted");
      if (e.id.empty() || e.id.find('/') != std::string::npos) violation("batch_list", "id that is not a file name accepted");
    }
  });
}

}  // namespace sl::test
