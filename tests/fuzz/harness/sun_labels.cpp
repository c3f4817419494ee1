// Harness: data/sun_labels.h read_sun_labels (streetlight-eval --sun-labels, pano_ldr/sun_labels.csv).
// Invariant: at least one row; each has a file name, rows' lines grow and follow the header; a
// visible sun has a position and a none sun has none; a position lies in the label frame and
// maps to a unit direction.
#include <cmath>

#include "data/sun_labels.h"
#include "tests/fuzz/harness/fuzz_harness.h"

namespace sl::test {

void fuzz_sun_labels(const uint8_t* data, size_t size) {
  const std::string path = write_scratch("sun_labels.csv", data, size);
  refuses_cleanly_or_runs("sun_labels", [&] {
    const data::SunLabels labels = data::read_sun_labels(path);
    if (labels.rows.empty()) violation("sun_labels", "no rows accepted");
    int last_line = 1;
    for (const auto& r : labels.rows) {
      if (r.file.empty()) violation("sun_labels", "a row without a file name accepted");
      if (r.line <= last_line) violation("sun_labels", "row lines do not grow after the header");
      last_line = r.line;
      if (r.sun == data::SunVisibility::Visible && !r.has_position) violation("sun_labels", "visible sun without a position");
      if (r.sun == data::SunVisibility::None && r.has_position) violation("sun_labels", "none label with a position");
      if (!r.has_position) continue;
      if (!(r.u >= 0 && r.u <= labels.frame_width && r.v >= 0 && r.v <= labels.frame_height))
        violation("sun_labels", "a position outside the label frame accepted");
      const glm::dvec3 d = labels.direction(r, 64, 32);
      if (!(std::abs(glm::length(d) - 1.0) < 1e-9)) violation("sun_labels", "direction is not a unit vector");
    }
  });
}

}  // namespace sl::test
