// streetlight-bench sun-features: what the networks' features know of the real sun, for linear
// probes across places (scripts/probe_sun_features.py, issue 53). For each crop with a known sun of
// the real-sky benchmark (one split of an HDR-sky folder or a labelled LDR panorama folder, K crops
// per panorama, the crops streetlight-eval scores) and for its mirror image, it writes one row of
// OUT/rows.csv and one row of each feature block OUT/<block>.npy (float32, [rows, dims]):
//   - backbone:          the lighting predictor's pooled features g of the network's input;
//   - statistics:        the 102 image statistics of that input (train/image_statistics.h);
//   - glare_azimuth:     the glare detector's azimuth-head input (its features pooled to 4×8 cells);
//   - glare_azimuth_p:   the detector's azimuth probabilities over its sectors;
//   - mobilenet:         an ImageNet MobileNetV2's pooled features of the network's input.
// rows.csv: row, panorama, place, crop, flip, the true sun (canonical frame of the view: −z is
// forward), whether it is in the crop, the label's confidence and scene, and the shipped
// estimator's sun (flip-averaged, with the detector), mirrored ((x, y, z) → (−x, y, z)) on the
// mirror rows. Places: places.csv of an LDR folder (data/places.h); an HDR sky is its own place.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "autodiff/ops.h"
#include "autodiff/tape.h"
#include "data/augment.h"
#include "data/places.h"
#include "nn/modules/mobilenet_v2.h"
#include "nn/modules/mobilenet_v2_tflite.h"
#include "tools/bench/bench.h"
#include "tools/common/cli.h"
#include "tools/common/released_models.h"
#include "train/image_statistics.h"
#include "train/inference.h"
#include "train/real_sky_benchmark.h"
#include "train/street_batch.h"
#include "train/sun_glare.h"
#include "util/error.h"
#include "util/file.h"

namespace sl::bench {
namespace {

// Rows of float32 features, written as a NumPy .npy file (format 1.0, C order).
struct FeatureBlock {
  explicit FeatureBlock(std::string n) : name(std::move(n)) {}
  std::string name;
  int64_t dims = -1;
  std::vector<float> values;
  void add(const Tensor& row) {
    const Tensor r = row.detach().to(DType::F32).contiguous();
    SL_CHECK(dims < 0 || r.numel() == dims, "sun-features: block ", name, " changed width: ", dims, " then ", r.numel());
    dims = r.numel();
    values.insert(values.end(), r.data<float>(), r.data<float>() + r.numel());
  }
  void add(const std::vector<double>& row) {
    SL_CHECK(dims < 0 || int64_t(row.size()) == dims, "sun-features: block ", name, " changed width");
    dims = int64_t(row.size());
    for (double v : row) values.push_back(float(v));
  }
  void write(const std::string& dir) const {
    const int64_t rows = dims > 0 ? int64_t(values.size()) / dims : 0;
    std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" + std::to_string(rows) + ", " +
                         std::to_string(std::max<int64_t>(dims, 0)) + "), }";
    while ((10 + header.size() + 1) % 64 != 0) header += ' ';
    header += '\n';
    std::string bytes = "\x93NUMPY";
    bytes += char(1);
    bytes += char(0);
    bytes += char(header.size() & 0xff);
    bytes += char((header.size() >> 8) & 0xff);
    bytes += header;
    bytes.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(float));
    write_file_atomic((std::filesystem::path(dir) / (name + ".npy")).string(), bytes);
  }
};

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

int run_sun_features(const std::vector<std::string>& args) {
  std::string data_dir, split_file, split = "val", out, checkpoint, glare_path, mobilenet_path =
      "../shared/data/weights/mobilenet_v2_1.0_224_quant.tflite";
  int64_t crops = 8, limit = 0;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&]() -> std::string {
      SL_CHECK(i + 1 < args.size(), "sun-features: ", a, " needs a value");
      return args[++i];
    };
    if (a == "--help" || a == "-h") {
      std::printf(
          "usage: streetlight-bench sun-features --data DIR --split-file FILE --split train|val|test --out OUT\n"
          "                                     [--crops K] [--limit N] [--checkpoint FILE] [--sun-glare FILE]\n"
          "                                     [--mobilenet FILE|none]\n\n"
          "Writes what the networks' features know of the real sun, for linear probes across places\n"
          "(scripts/probe_sun_features.py): for each crop with a known sun of one split of DIR (HDR skies or labelled\n"
          "LDR panoramas, streetlight-eval's crops, K per panorama, default 8; the first N panoramas with --limit) and\n"
          "for its mirror image, a row of OUT/rows.csv (panorama, place, the true sun in the view's canonical frame,\n"
          "the shipped estimator's sun) and of OUT/backbone.npy (the lighting predictor's pooled features),\n"
          "OUT/statistics.npy (102 image statistics), OUT/glare_azimuth.npy and OUT/glare_azimuth_p.npy (the glare\n"
          "detector's azimuth-head input and probabilities) and OUT/mobilenet.npy (an ImageNet MobileNetV2's pooled\n"
          "features; default weights %s, none to skip). Defaults: the released model and detector.\n",
          mobilenet_path.c_str());
      return 0;
    }
    if (a == "--data") data_dir = value();
    else if (a == "--split-file") split_file = value();
    else if (a == "--split") split = value();
    else if (a == "--out") out = value();
    else if (a == "--crops") crops = cli::parse_integer("sun-features: --crops", value(), 1, 1024);
    else if (a == "--limit") limit = cli::parse_integer("sun-features: --limit", value(), 0, 1 << 30);
    else if (a == "--checkpoint") checkpoint = value();
    else if (a == "--sun-glare") glare_path = value();
    else if (a == "--mobilenet") mobilenet_path = value();
    else SL_CHECK(false, "sun-features: unknown option '", a, "' (try --help)");
  }
  SL_CHECK(!data_dir.empty(), "sun-features: --data DIR is required");
  SL_CHECK(!split_file.empty(), "sun-features: --split-file FILE is required (probes are fitted on one split, read on others)");
  SL_CHECK(!out.empty(), "sun-features: --out OUT is required");
  SL_CHECK(split == "train" || split == "val" || split == "test", "sun-features: --split must be train, val or test, got '",
           split, "'");
  if (checkpoint.empty()) checkpoint = cli::released_model_path();
  if (glare_path.empty()) glare_path = cli::released_sun_glare_path();

  train::LightingEstimator est(checkpoint);
  auto detector = train::load_sun_glare(glare_path);
  SL_CHECK(detector->has_azimuth(), "sun-features: --sun-glare '", glare_path, "' has no azimuth head");
  est.set_sun_glare(detector);
  std::shared_ptr<nn::MobileNetV2> mobilenet;
  if (mobilenet_path != "none") {
    SL_CHECK(std::filesystem::exists(mobilenet_path), "sun-features: --mobilenet '", mobilenet_path,
             "' does not exist (none skips the block)");
    mobilenet = std::make_shared<nn::MobileNetV2>();
    nn::load_mobilenet_v2_tflite(*mobilenet, mobilenet_path);
    mobilenet->eval();
  }

  const bool ldr = train::is_ldr_panorama_folder(data_dir);
  const std::string labels_file = (std::filesystem::path(data_dir) / "sun_labels.csv").string();
  const train::RealSkyFolder folder =
      ldr ? train::load_ldr_panorama_folder(data_dir, labels_file, split_file, split, int(crops), limit)
          : train::load_hdr_sky_folder(data_dir, split_file, split, int(crops), limit);
  data::Places places;
  const std::string places_file = (std::filesystem::path(data_dir) / "places.csv").string();
  if (ldr && std::filesystem::exists(places_file)) places = data::read_places(places_file);

  std::filesystem::create_directories(out);
  FeatureBlock backbone("backbone"), statistics("statistics"), glare_features("glare_azimuth"),
      glare_p("glare_azimuth_p"), mobile("mobilenet");
  std::ostringstream rows;
  rows << "row,panorama,place,crop,flip,sun_x,sun_y,sun_z,in_crop,confidence,scene,est_x,est_y,est_z\n";
  const auto& po = est.predictor().options();
  int64_t known = 0;
  for (const train::RealSkyCrop& c : folder.test) known += c.sun_known;
  cli::Progress progress("sun-features", known);
  int64_t row = 0, done = 0;
  std::string last_panorama;
  int crop_index = -1;
  for (const train::RealSkyCrop& c : folder.test) {
    crop_index = c.panorama == last_panorama ? crop_index + 1 : 0;
    last_panorama = c.panorama;
    if (!c.sun_known || c.sample.views.empty()) continue;
    const data::StreetView& v = c.sample.views[0];
    const glm::dvec3 answer = est.estimate({{v.ldr, v.depth, v.camera}}).sun_direction_canonical;
    const std::string place = ldr ? places.place_of(c.panorama) : c.panorama;
    for (int flip = 0; flip < 2; ++flip) {
      const Tensor image = flip ? data::flip_horizontal(v.ldr.contiguous()) : v.ldr;
      const double m = flip ? -1.0 : 1.0;
      {
        NoGradGuard no_grad;
        const Tensor input = unsqueeze(train::resize_bilinear(image, po.image_height, po.image_width), 0);
        backbone.add(est.predictor().features(input));
        statistics.add(train::image_statistics(input));
        const Tensor g = unsqueeze(train::glare_input(image), 0);
        glare_features.add(detector->azimuth_features(g));
        const train::GlareHeads h = detector->forward_heads(g);
        glare_p.add(train::read_glare(select(h.glare, 0, 0), int(image.size(1)), int(image.size(2)), select(h.azimuth, 0, 0))
                        .azimuth);
        if (mobilenet) mobile.add(mobilenet->forward(nn::imagenet_input(input)));
      }
      char buf[512];
      std::snprintf(buf, sizeof buf, ",%d,%d,%.6f,%.6f,%.6f,%d,%s,%s,%.6f,%.6f,%.6f\n", crop_index, flip,
                    m * c.sun_canonical.x, c.sun_canonical.y, c.sun_canonical.z, int(c.sun_in_crop),
                    csv_field(c.label_confidence).c_str(), csv_field(c.scene).c_str(), m * answer.x, answer.y, answer.z);
      rows << row++ << ',' << csv_field(c.panorama) << ',' << csv_field(place) << buf;
    }
    progress.update(++done);
  }
  progress.finish();
  for (const FeatureBlock* b : {&backbone, &statistics, &glare_features, &glare_p, &mobile})
    if (b->dims > 0) b->write(out);
  write_file_atomic((std::filesystem::path(out) / "rows.csv").string(), rows.str());
  std::printf("sun-features: %lld rows (%lld crops with a known sun and their mirror images) of %s split %s -> %s\n",
              static_cast<long long>(row), static_cast<long long>(done), data_dir.c_str(), split.c_str(), out.c_str());
  return 0;
}

const Registrar reg("sun-features", "writes the networks' features of the real-sky crops for linear probes across places",
                    &run_sun_features);

}  // namespace
}  // namespace sl::bench
