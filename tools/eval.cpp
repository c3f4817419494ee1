// streetlight-eval: the paper's metrics (Sec 4.2, Tables 1-2) for one or more checkpoints on a
// generated street dataset (docs/DATASET.md) or a folder of real HDR panoramas.
//
//   lighting checkpoints: sun direction median/mean angular error (f̂_dir, or the peak of the
//     predicted dome for branches without a sky vector); novel-view LDR PSNR and si-PSNR (all
//     pixels, and pixels whose ray points into the upper hemisphere); on the generator's data,
//     insertion against the path-traced ground truth (PSNR over the object and its shadow
//     region, mean absolute shadow-ratio error); lighting inference time per image; and
//     "sun_per_image": each labelled image's id (a street sample, or "<panorama>#<crop>"), its
//     sun error and the predicted and true directions in the input camera's canonical frame.
//   folders of LDR panoramas (8-bit JPEG/PNG with a sun_labels.csv, data/sun_labels.h; e.g.
//     ../shared/data/pano_ldr with configs/pano_ldr_split.json): the same crops as the HDR skies
//     with the true sun from the label (train/real_sky_benchmark.h ldr_panorama_crops), reported
//     apart ("kind": "ldr_panoramas") and split by the label's scene (street / other) and with the
//     low-confidence labels apart, each beside the constant baseline; panoramas without a sun
//     position (none, or occluded without one) are counted and listed, not scored.
//   confidence: each labelled image's flip spread (train/inference.h sun_flip_spread_deg), sun
//     height (sun_hedge) and crop spread (sun_crop_spread_deg) in "sun_per_image", and for each
//     measure ("sun_confidence" by the flip spread, "sun_confidence_hedge" by the height,
//     "sun_confidence_crop" by the crop spread, "sun_confidence_probability" by the sun head's
//     probability near its mode, per image "sun_probability" and its complement "sun_doubt") the median sun error of the most confident half of the
//     images against the rest's, each with its 95% interval (train/sun_confidence.h: does a small
//     measure mean a small error?); on LDR panoramas also per scene by the doubt
//     ("sun_confidence_probability_by_scene": street / other). The per-image "predicted_sun_share" is the predicted sky's
//     share of its light near its sun.
//   the sun error in parts ("sun_parts", train/sun_error_parts.h): the median azimuth error, the
//     median elevation bias (predicted − true) and how often the predicted sun is in the other
//     half of the sphere (in front of the view or behind it) than the true one.
//   sun in crop, pooled: with two or more real data sets (e.g. the HDR and the LDR test splits),
//     "sun_in_crop_pooled" holds each checkpoint's median error over every crop whose sun is
//     inside it, from all of them, with its interval (whole panoramas resampled).
//   sky-autoencoder checkpoints: sky log-L2 = mean (ln(1 + L̂) − ln(1 + L))² of the
//     reconstructed exposure-normalised dome, and the sun angular error of f_dir.
// Error against run time (--out): the first lighting checkpoint is re-run at several insertion
// budgets (light samples of Eq. 2, shadow rays of Eq. 4); error_time.png plots its shadow-ratio
// error against the ground truth against lighting + insertion time in ms (one line per checkpoint).
// The scoring itself is tools/common/evaluation.h (shared with the Python module's
// streetlight.evaluate); this file is the command line.
#include <cmath>
#include <iostream>
#include <string>

#include "tools/common/cli.h"
#include "tools/common/evaluation.h"

using sl::cli::EvalOptions;
using sl::cli::EvalReport;
using sl::cli::evaluate;
using sl::cli::write_eval_report;

namespace {

int run(int argc, char** argv) {
  sl::cli::Args a("streetlight-eval",
              "streetlight-eval [--checkpoint CKPT ...] --data DIR [--data DIR2 ...] [--split test] [--hdri-split FILE]\n"
              "                 [--ldr-split FILE] [--sun-labels FILE] [--crops K] [--baseline-data DIR] [--out DIR] [--json]\n\n"
              "Evaluates checkpoints with the metrics of Wang et al. ECCV 2022 (Tables 1-2): sun direction angular\n"
              "error, novel-view LDR PSNR / si-PSNR (also upper hemisphere only), sky log-L2 (sky autoencoder),\n"
              "insertion error against the generator's path-traced ground truth (also under oracle lighting: the\n"
              "generator's own HDR panorama at the camera, which isolates the renderer's error), and inference\n"
              "time. Each DIR is a\n"
              "streetlight-datagen dataset or a folder of real HDR panoramas; results are reported per DIR.\n"
              "Real panoramas (the real-sky benchmark): K seeded perspective crops per panorama of the split's\n"
              "--split list (default: every file), sun errors over the crops whose sun is hard, also split by\n"
              "whether the sun is inside the crop, beside the constant baseline (the mean sun direction of the\n"
              "split file's training panoramas). On generated streets the constant baseline is the mean sun of\n"
              "the train split of --baseline-data (default: of the same DIR, when it has one). Samples whose sun\n"
              "is soft carry no sun error. Every metric has a 95% bootstrap interval ([lo, hi]; 2000 resamples,\n"
              "a real panorama's crops resampled together). Without --checkpoint: the released model\n"
              "(models/streetlight.safetensors).\n"
              "A folder of LDR panoramas (8-bit .jpg/.jpeg/.png beside a sun_labels.csv, e.g. ../shared/data/pano_ldr):\n"
              "the same crops, read as the photo's own 8-bit values, with the true sun from the hand label; split by\n"
              "--ldr-split (e.g. configs/pano_ldr_split.json), reported apart and also by the label's scene (street,\n"
              "other) and for the low-confidence labels alone; panoramas without a sun position are listed, not scored.",
              {{"--checkpoint", "CKPT", "checkpoint to evaluate (one table row each; default: the released model)", true},
               {"--name", "NAME", "row name for the matching --checkpoint (default: its file path)", true},
               {"--data", "DIR", "street dataset (index.json) or folder of .hdr/.exr panoramas", true},
               {"--split", "NAME", "dataset split, or the split of --hdri-split (default test)"},
               {"--hdri-split", "FILE", "split file for HDR panorama folders (e.g. configs/hdri_split.json)"},
               {"--ldr-split", "FILE", "split file for LDR panorama folders (e.g. configs/pano_ldr_split.json)"},
               {"--sun-labels", "FILE", "sun labels of the LDR panorama folders (default: DIR/sun_labels.csv)"},
               {"--crops", "K", "perspective crops per real panorama (default 8)"},
               {"--limit", "N", "evaluate at most N images (panorama folders: N panoramas)"},
               {"--view-rows", "N", "rows at which novel views are rendered (default 32)"},
               {"--baseline-data", "DIR", "street dataset whose train split gives the constant baseline of street --data"},
               {"--no-budgets", "", "skip the error-against-time sweep"},
               {"--no-flip-average", "", "one network pass per image for the sun, instead of averaging it with the left-right\n"
                                         "mirrored image's (the estimator's default)"},
               {"--crop-scales", "LIST", "centred crops whose suns are averaged with the image's, as fractions of its size\n"
                "                               (default none: off; 0.55,0.7,0.85 was chosen on validation,\n"
                "                               docs/RESULTS.md; adds the crop-spread confidence)"},
               {"--no-visible-sun", "", "keep the network's sun even where the photo shows the sun disk (by default a visible\n"
                "                               sun sets the direction, data/visible_sun.h); the sun rows count the images\n"
                "                               where it fired (\"cue k\" in the table, visible_sun_fired in the JSON)"},
               {"--sun-glare", "FILE", "the learned sun-glare detector behind the disk test (default: the released one,\n"
                "                               models/sun_glare.safetensors, when present; train/sun_glare.h)"},
               {"--no-sun-glare", "", "the disk test alone finds a visible sun"},
               {"--glare-azimuth-weight", "W", "the exponent of the detector's azimuth head where it reweighs the sun head's\n"
                "                               distribution (default the released choice, train/sun_glare.h; 0 off; only for\n"
                "                               a detector with an azimuth head)"},
               {"--glare-map-weight", "W", "the exponent of the detector's glare map where, below its threshold, it reweighs the\n"
                "                               sun head's distribution (default the released choice, train/sun_glare.h; 0 off)"},
               {"--out", "DIR", "write results.json, results.md and error_time.png here"},
               {"--json", "", "print the results as one JSON object on stdout"}});
  if (!a.parse(argc, argv)) return 0;
  EvalOptions o;
  o.checkpoints = a.all("--checkpoint");
  o.names = a.all("--name");
  o.data = a.all("--data");
  SL_CHECK(!o.data.empty(), "--data DIR is required");
  o.split = a.get("--split", "test");
  o.hdri_split = a.get("--hdri-split", "");
  o.limit = a.integer("--limit", 0);
  o.view_rows = static_cast<int>(a.integer("--view-rows", 32));
  o.crop_scales = a.numbers("--crop-scales", {}, 0.0, 1.0);
  o.crops = static_cast<int>(a.integer("--crops", 8));
  o.ldr_split = a.get("--ldr-split", "");
  o.sun_labels = a.get("--sun-labels", "");
  o.baseline_data = a.get("--baseline-data", "");
  o.budgets = a.has("--out") && !a.has("--no-budgets");
  o.flip_average = !a.has("--no-flip-average");
  o.visible_sun = !a.has("--no-visible-sun");
  if (o.visible_sun && !a.has("--no-sun-glare"))
    o.sun_glare = a.has("--sun-glare") ? a.get("--sun-glare") : sl::cli::released_sun_glare_path();
  o.glare_azimuth_weight = a.number("--glare-azimuth-weight", o.glare_azimuth_weight);
  SL_CHECK(std::isfinite(o.glare_azimuth_weight) && o.glare_azimuth_weight >= 0.0,
           "--glare-azimuth-weight must be a finite number >= 0, got ", o.glare_azimuth_weight);
  o.glare_map_weight = a.number("--glare-map-weight", o.glare_map_weight);
  SL_CHECK(std::isfinite(o.glare_map_weight) && o.glare_map_weight >= 0.0,
           "--glare-map-weight must be a finite number >= 0, got ", o.glare_map_weight);
  const EvalReport report = evaluate(o);
  if (a.has("--out")) write_eval_report(report, a.get("--out"));
  if (a.has("--json")) std::cout << report.results.dump() << "\n";
  else std::cout << report.markdown;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return sl::cli::run_main([&] { return run(argc, argv); });
}
