// streetlight-eval's evaluation core (tools/eval.cpp is its command line; the Python module's
// streetlight.evaluate calls it too): every checkpoint scored on every data folder with the
// paper's metrics (Sec 4.2, Tables 1-2), the real-sky and LDR-panorama benchmarks, the
// confidence halves and the pooled sun-in-crop table. tools/eval.cpp's header comment describes
// each metric and results.json's keys.
//
// Contract:
// - evaluate() returns what streetlight-eval writes: results.json's object, results.md's text and
//   the points of error_time.png. The numbers do not depend on who calls it (tool or Python).
// - Bad options (no data, a name count that does not match, non-positive crops or rows, crop
//   scales outside (0, 1)) are sl::Error before any work (check_eval_options); so are unreadable
//   checkpoints, split files, sun labels and data folders (the files are opened before scoring).
// - Timing fields ("inference_ms", and "ms" of each "budgets" entry) are wall-clock and vary
//   from run to run; everything else is deterministic for the same inputs.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tools/common/plot.h"
#include "train/sun_glare.h"

namespace sl::cli {

struct EvalOptions {
  std::vector<std::string> checkpoints;  // empty: the released model, named "released model"
  std::vector<std::string> names;        // one per checkpoint, or empty: the checkpoint paths
  std::vector<std::string> data;         // street datasets (index.json) or panorama folders
  std::string split = "test";            // dataset split, or the split of hdri_split / ldr_split
  std::string hdri_split;                // split file of HDR panorama folders ("" none)
  std::string ldr_split;                 // split file of LDR panorama folders ("" none)
  std::string sun_labels;                // LDR folders' labels ("" DIR/sun_labels.csv)
  int crops = 8;                         // perspective crops per real panorama
  int64_t limit = 0;                     // at most this many images (panorama folders: panoramas); 0 all
  int view_rows = 32;                    // rows of the rendered novel views
  std::string baseline_data;             // street dataset of the constant baseline ("" the data's own)
  bool budgets = false;                  // the error-against-time sweep (the tool: with --out)
  bool flip_average = true;              // average the sun with the mirrored image's
  std::string sun_glare;                 // the learned sun-glare detector behind it ("" none)
  double glare_azimuth_weight = train::kGlareAzimuthWeight;  // its azimuth head's weight (LightingEstimator::set_sun_glare)
  double glare_map_weight = train::kGlareMapWeight;          // its glare map's weight (the same)
  bool visible_sun = true;               // a visible sun disk sets the direction
  std::vector<double> crop_scales;       // centred crops averaged into the sun (empty: off)
  // Called after each scored image (from the calling thread); may throw to stop the evaluation.
  std::function<void()> on_image;
};

struct EvalReport {
  nlohmann::json results;         // results.json
  std::string markdown;           // results.md (and the tool's stdout)
  std::vector<PlotPoint> plot;    // error_time.png's points (empty without budgets)
};

// Checks the options' values (not the files); sl::Error naming the option otherwise.
void check_eval_options(const EvalOptions& o);

// Scores every checkpoint on every data folder (check_eval_options first).
EvalReport evaluate(const EvalOptions& o);

// Writes results.json, results.md and (when it has points) error_time.png into `out`.
void write_eval_report(const EvalReport& r, const std::string& out);

}  // namespace sl::cli
