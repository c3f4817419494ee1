// Training configuration defaults and their conversion. See train_config.h; every key is
// documented in configs/README.md.
#include "train/train_config.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "util/error.h"

using sl::render::InsertionOptions;
using sl::render::parse_sample_spacing;
using sl::render::RadianceQueryOptions;
using sl::render::VsgGrid;

namespace sl::train {

using nlohmann::json;

json default_train_config() {
  return json{
      {"stage", kStageSky},
      {"seed", 0},
      {"init", {{"sky_checkpoint", ""}, {"checkpoint", ""}, {"reinitialise", json::array()}, {"sun_backbone_weights", ""}}},
      {"data",
       {{"dataset", ""},
        {"train_split", "train"},
        {"val_split", "val"},
        {"hdri_dir", ""},
        {"hdri_fraction", 0.3},
        {"hdri_split", ""},
        {"hdri_train_split", "train"},
        {"hdri_val_split", "val"},
        {"real_fraction", 0.0},
        {"flip", false},
        {"real_val_crops", 4},
        {"real_fov_deg", {50.0, 80.0}},
        {"real_pitch_deg", 10.0},
        {"real_white_balance_stops", 0.15},
        {"real_exposure_stops", 0.5},
        {"ldr_dir", ""},
        {"ldr_split", ""},
        {"ldr_labels", ""},
        {"ldr_fraction", 0.0},
        {"ldr_val_crops", 4},
        {"ldr_low_label_weight", 1.0},
        {"ldr_place_balance", 1.0},
        {"ldr_places", ""},
        {"real_tone_stops", 0.0},
        {"sun_aim_share", 0.0},
        {"ldr_working_width", 1024},
        {"exposure_stops", 1.0},
        {"ldr_key", 0.25},
        {"val_size", 16},
        {"cache_mb", 4096},
        {"pano_rays", 512},
        {"view_rays", 512},
        {"val_view_height", 32}}},
      {"model",
       {{"sky",
         {{"height", 32}, {"width", 128}, {"code_dim", 64}, {"base_channels", 16}, {"hidden", 256},
          {"sun_lobe_texels", 1.0}}},
        {"image_height", 128},
        {"image_width", 256},
        {"backbone_depth", 18},
        {"backbone_width", 64},
        {"head_hidden", 256},
        {"head_grid_channels", 0},
        {"sun_grid", {{"elevation_bins", 0}, {"azimuth_bins", 0}}},
        {"sun_image_statistics", false},
        {"sun_backbone", ""},
        {"sun_backbone_channels", 16},
        {"sky_branch", "sky_decoder"},
        {"volume_branch", true},
        {"volume",
         {{"dims", {64, 64, 16}},
          {"extent_neg_m", {150.0, 5.0, 150.0}},
          {"extent_pos_m", {150.0, 75.0, 150.0}},
          {"log_scale_m", 5.0},
          {"coarse_scale", 8},
          {"coarse_channels", 8},
          {"unet_channels", 8},
          {"unet_depth", 3},
          {"samples", 64},
          {"spacing", "grid"},
          {"trilinear", false}}},
        {"discriminator", {{"base_channels", 32}, {"layers", 3}, {"norm", "instance"}}}}},
      {"loss",
       {{"ae_direction", 1.0},
        {"ae_intensity", 0.1},
        {"ae_hdr", 1.0},
        {"sky_intensity", 0.1},
        {"sky_latent", 1.0},
        {"sky_direction", 1.0},
        {"sky_direction_form", "angular"},
        {"sun_energy", 0.0},
        {"ldr_sun_energy", 0.0},
        {"ldr_sun_energy_range", {1.0, 10.0}},
        {"sun_distribution", 0.0},
        {"sun_distribution_width_deg", 8.0},
        {"sun_half", 0.0},
        {"domain_adversarial", 0.0},
        {"domain_reversal", 1.0},
        {"domain_lr_scale", 1.0},
        {"low_sun_weight", 0.0},
        {"low_sun_below_deg", 30.0},
        {"sky_ldr", 1.0},
        {"sky_hdr", 1.0},
        {"radiance", 1.0},
        {"depth", 0.1},
        {"sky_separation", 0.1},
        {"adversarial", 0.01}}},
      {"optim",
       {{"lr", 1e-3},
        {"min_lr", 1e-5},
        {"warmup_steps", 20},
        {"schedule_steps", 0},
        {"weight_decay", 0.0},
        {"ema_decay", 0.0},
        {"clip_grad_norm", 10.0},
        {"discriminator_lr", 2e-4}}},
      {"train",
       {{"steps", 2000},
        {"batch_size", 4},
        {"log_every", 10},
        {"val_every", 200},
        {"checkpoint_every", 200},
        {"image_every", 200},
        {"best_metric", "val_loss"},
        {"global_batch", 0},
        {"freeze", json::array()}}},
      {"insertion",
       {{"placement", "dataset"},
        {"aa_samples", 1},
        {"light_samples", 16},
        {"shadow_width", 80},
        {"shadow_height", 45},
        {"shadow_rays", 128},
        {"ambient", 0.1},
        {"importance_sampling", true},
        {"real", "renderer"}}},
  };
}

namespace {

void positive(const json& c, const char* section, const char* key) {
  const double v = c.at(section).at(key).get<double>();
  SL_CHECK(v > 0, section, ".", key, " must be positive, got ", v);
}

}  // namespace

void check_train_config(const json& c) {
  const std::string stage = c.at("stage").get<std::string>();
  SL_CHECK(stage == kStageSky || stage == kStageLighting || stage == kStageAdversarial,
           "stage must be \"sky_autoencoder\", \"lighting\" or \"adversarial\", got \"", stage, "\"");
  for (const char* k : {"steps", "batch_size", "log_every", "val_every", "checkpoint_every", "image_every"})
    positive(c, "train", k);
  SL_CHECK(c.at("train").at("global_batch").get<int64_t>() >= 0, "train.global_batch must be >= 0 (0: ranks × "
           "train.batch_size), got ", c.at("train").at("global_batch").get<int64_t>());
  const json& freeze = c.at("train").at("freeze");
  SL_CHECK(freeze.is_array() && std::all_of(freeze.begin(), freeze.end(), [](const json& v) { return v.is_string(); }),
           "train.freeze must be a list of module names, got ", freeze.dump());
  SL_CHECK(freeze.empty() || stage != kStageSky, "train.freeze names parts of the lighting predictor; the ",
           kStageSky, " stage has none to freeze, got ", freeze.dump());
  positive(c, "optim", "lr");
  SL_CHECK(c.at("optim").at("min_lr").get<double>() >= 0, "optim.min_lr must be >= 0");
  SL_CHECK(c.at("optim").at("schedule_steps").get<int64_t>() >= 0,
           "optim.schedule_steps must be >= 0 (0: train.steps), got ", c.at("optim").at("schedule_steps").get<int64_t>());
  const double ema = c.at("optim").at("ema_decay").get<double>();
  SL_CHECK(ema >= 0 && ema < 1, "optim.ema_decay must lie in [0, 1) (0: off), got ", ema);
  SL_CHECK(c.at("seed").get<int64_t>() >= 0, "seed must be >= 0, got ", c.at("seed").get<int64_t>());
  const double frac = c.at("data").at("hdri_fraction").get<double>();
  SL_CHECK(frac >= 0 && frac <= 1, "data.hdri_fraction must lie in [0, 1], got ", frac);
  const int64_t cache_mb = c.at("data").at("cache_mb").get<int64_t>();
  SL_CHECK(cache_mb >= 0 && cache_mb <= (int64_t{1} << 24), "data.cache_mb must lie in [0, 16777216] (0: off), got ",
           cache_mb);
  const double real = c.at("data").value("real_fraction", 0.0);
  SL_CHECK(real >= 0 && real < 1, "data.real_fraction must lie in [0, 1), got ", real);
  SL_CHECK(real == 0 || !c.at("data").at("hdri_dir").get<std::string>().empty(),
           "data.real_fraction > 0 needs data.hdri_dir (a folder of real HDR panoramas)");
  const double ldr = c.at("data").at("ldr_fraction").get<double>();
  SL_CHECK(ldr >= 0 && ldr < 1 && real + ldr < 1, "data.ldr_fraction must lie in [0, 1) and leave room for the "
           "generated streets (data.real_fraction + data.ldr_fraction < 1), got ", ldr, " with data.real_fraction ", real);
  SL_CHECK(ldr == 0 || !c.at("data").at("ldr_dir").get<std::string>().empty(),
           "data.ldr_fraction > 0 needs data.ldr_dir (a folder of real LDR panoramas with sun_labels.csv)");
  SL_CHECK(c.at("data").at("ldr_val_crops").get<int64_t>() >= 0, "data.ldr_val_crops must be >= 0");
  if (real > 0 || ldr > 0) {
    const auto fov = c.at("data").at("real_fov_deg").get<std::vector<double>>();
    SL_CHECK(fov.size() == 2 && fov[0] > 0 && fov[0] <= fov[1] && fov[1] < 179,
             "data.real_fov_deg must be [min, max] with 0 < min <= max < 179");
    SL_CHECK(c.at("data").at("real_val_crops").get<int64_t>() >= 0, "data.real_val_crops must be >= 0");
  }
  if (stage == kStageLighting) {
    const std::string branch = c.at("model").at("sky_branch").get<std::string>();
    SL_CHECK(branch == "constant" || !c.at("init").at("sky_checkpoint").get<std::string>().empty() ||
                 !c.at("init").at("checkpoint").get<std::string>().empty(),
             "stage lighting starts from the frozen sky autoencoder: set init.sky_checkpoint to the stage-1 "
             "checkpoint (e.g. runs/sky/last.safetensors), or init.checkpoint to a lighting checkpoint");
    SL_CHECK(!c.at("data").at("dataset").get<std::string>().empty(),
             "stage lighting needs data.dataset (a street-scene dataset folder)");
  }
  if (stage == kStageAdversarial) {
    SL_CHECK(!c.at("init").at("checkpoint").get<std::string>().empty(),
             "stage adversarial starts from the lighting stage: set init.checkpoint to its checkpoint "
             "(e.g. runs/lighting/last.safetensors)");
    SL_CHECK(!c.at("data").at("dataset").get<std::string>().empty(),
             "stage adversarial needs data.dataset (a street-scene dataset folder)");
    const std::string p = c.at("insertion").at("placement").get<std::string>();
    SL_CHECK(p == "dataset", "insertion.placement must be \"dataset\" (the generator's placement on drivable ground, "
             "collision- and occlusion-checked against the depth), got \"", p, "\"");
    const std::string real = c.at("insertion").value("real", std::string("renderer"));
    SL_CHECK(real == "renderer" || real == "path_traced",
             "insertion.real must be \"renderer\" or \"path_traced\", got \"", real, "\"");
  }
  const std::string form = c.at("loss").at("sky_direction_form").get<std::string>();
  SL_CHECK(form == "elevation_azimuth" || form == "angular",
           "loss.sky_direction_form must be \"elevation_azimuth\" or \"angular\", got \"", form, "\"");
  const int64_t ldr_width = c.at("data").at("ldr_working_width").get<int64_t>();
  SL_CHECK(ldr_width >= 64 && ldr_width <= 8192 && ldr_width % 2 == 0,
           "data.ldr_working_width must be even and in [64, 8192], got ", ldr_width);
  const double tone = c.at("data").at("real_tone_stops").get<double>();
  SL_CHECK(std::isfinite(tone) && tone >= 0 && tone <= 2, "data.real_tone_stops must lie in [0, 2], got ", tone);
  const double aim = c.at("data").at("sun_aim_share").get<double>();
  SL_CHECK(std::isfinite(aim) && aim >= 0 && aim <= 1, "data.sun_aim_share must lie in [0, 1], got ", aim);
  const double balance = c.at("data").at("ldr_place_balance").get<double>();
  SL_CHECK(std::isfinite(balance) && balance >= 0 && balance <= 1, "data.ldr_place_balance must lie in [0, 1], got ",
           balance);
  const double low = c.at("data").at("ldr_low_label_weight").get<double>();
  SL_CHECK(std::isfinite(low) && low >= 0 && low <= 1, "data.ldr_low_label_weight must lie in [0, 1], got ", low);
  const double width = c.at("loss").at("sun_distribution_width_deg").get<double>();
  SL_CHECK(std::isfinite(width) && width > 0 && width <= 90, "loss.sun_distribution_width_deg must lie in (0, 90], got ",
           width);
  SL_CHECK(c.at("loss").at("sun_distribution").get<double>() == 0 ||
               c.at("model").at("sun_grid").at("elevation_bins").get<int64_t>() > 0,
           "loss.sun_distribution > 0 needs model.sun_grid (elevation_bins and azimuth_bins)");
  SL_CHECK(c.at("init").at("reinitialise").is_array() &&
               (c.at("init").at("reinitialise").empty() || !c.at("init").at("checkpoint").get<std::string>().empty()),
           "init.reinitialise names parts of the model in init.checkpoint to start afresh: it needs init.checkpoint");
  SL_CHECK(c.at("loss").at("sun_half").get<double>() == 0 ||
               (c.at("model").at("sun_grid").at("azimuth_bins").get<int64_t>() > 0 &&
                c.at("model").at("sun_grid").at("azimuth_bins").get<int64_t>() % 4 == 0),
           "loss.sun_half > 0 needs model.sun_grid with azimuth_bins a multiple of 4");
  const double domain = c.at("loss").at("domain_adversarial").get<double>();
  const double reversal = c.at("loss").at("domain_reversal").get<double>();
  SL_CHECK(std::isfinite(domain) && domain >= 0, "loss.domain_adversarial must be finite and >= 0, got ", domain);
  SL_CHECK(std::isfinite(reversal) && reversal >= 0, "loss.domain_reversal must be finite and >= 0, got ", reversal);
  const double domain_lr = c.at("loss").at("domain_lr_scale").get<double>();
  SL_CHECK(std::isfinite(domain_lr) && domain_lr > 0, "loss.domain_lr_scale must be finite and > 0, got ", domain_lr);
  SL_CHECK(domain == 0 || c.at("stage").get<std::string>() == kStageLighting,
           "loss.domain_adversarial is a term of stage 2 (\"lighting\"), not of stage \"", c.at("stage").get<std::string>(), "\"");
  SL_CHECK(domain == 0 || c.at("data").at("real_fraction").get<double>() + c.at("data").at("ldr_fraction").get<double>() > 0,
           "loss.domain_adversarial > 0 needs real crops beside the generated streets (data.real_fraction or ",
           "data.ldr_fraction)");
  const double low_sun = c.at("loss").at("low_sun_weight").get<double>();
  const double low_sun_below = c.at("loss").at("low_sun_below_deg").get<double>();
  SL_CHECK(std::isfinite(low_sun) && low_sun >= 0, "loss.low_sun_weight must be finite and >= 0, got ", low_sun);
  SL_CHECK(std::isfinite(low_sun_below) && low_sun_below > 0 && low_sun_below <= 90,
           "loss.low_sun_below_deg must lie in (0, 90], got ", low_sun_below);
  const json& range = c.at("loss").at("ldr_sun_energy_range");
  SL_CHECK(range.is_array() && range.size() == 2 && range[0].is_number() && range[1].is_number() &&
               range[0].get<double>() >= 0 && range[0].get<double>() <= range[1].get<double>() &&
               std::isfinite(range[1].get<double>()),
           "loss.ldr_sun_energy_range must be [lo, hi] with 0 <= lo <= hi, got ", range.dump());
  (void)sky_options(c);
  if (stage != kStageSky) (void)predictor_options(c), (void)volume_query_options(c);
}

SkyAutoencoderOptions sky_options(const json& c) {
  const json& s = c.at("model").at("sky");
  SkyAutoencoderOptions o;
  o.height = s.at("height").get<int64_t>();
  o.width = s.at("width").get<int64_t>();
  o.code_dim = s.at("code_dim").get<int64_t>();
  o.base_channels = s.at("base_channels").get<int64_t>();
  o.hidden = s.at("hidden").get<int64_t>();
  o.sun_lobe_texels = s.at("sun_lobe_texels").get<double>();
  o.seed = c.at("seed").get<uint64_t>();
  return o;
}

LightingPredictorOptions predictor_options(const json& c) {
  const json& m = c.at("model");
  const json& v = m.at("volume");
  LightingPredictorOptions o;
  o.image_height = m.at("image_height").get<int64_t>();
  o.image_width = m.at("image_width").get<int64_t>();
  o.backbone_depth = m.at("backbone_depth").get<int>();
  o.backbone_width = m.at("backbone_width").get<int64_t>();
  o.head_hidden = m.at("head_hidden").get<int64_t>();
  // Checkpoints written before the key existed pooled globally.
  o.head_grid_channels = m.value("head_grid_channels", int64_t{0});
  // Checkpoints written before the key existed had no sun head.
  const json grid = m.value("sun_grid", json::object());
  o.sun_grid.elevation_bins = grid.value("elevation_bins", int64_t{0});
  o.sun_grid.azimuth_bins = grid.value("azimuth_bins", int64_t{0});
  o.sun_image_statistics = m.value("sun_image_statistics", false);  // absent before 0.7.2
  o.sun_backbone = m.value("sun_backbone", std::string());          // absent before 0.7.5
  o.sun_backbone_channels = m.value("sun_backbone_channels", int64_t{16});
  o.sky_branch = m.at("sky_branch").get<std::string>();
  o.volume_branch = m.at("volume_branch").get<bool>();
  const auto dims = v.at("dims").get<std::vector<int64_t>>();
  SL_CHECK(dims.size() == 3 && dims[0] > 0 && dims[1] > 0 && dims[2] > 0,
           "model.volume.dims must be three positive integers [X, Y, Z]");
  o.vsg_dims = {dims[0], dims[1], dims[2]};
  o.coarse_scale = v.at("coarse_scale").get<int64_t>();
  o.coarse_channels = v.at("coarse_channels").get<int64_t>();
  o.unet_channels = v.at("unet_channels").get<int64_t>();
  o.unet_depth = v.at("unet_depth").get<int>();
  o.sky = sky_options(c);
  o.seed = c.at("seed").get<uint64_t>() + 1;
  validate(o);
  return o;
}

InsertionOptions training_insertion_options(const json& c, uint64_t seed) {
  const json& ic = c.at("insertion");
  InsertionOptions o;
  o.aa_samples = ic.at("aa_samples").get<int>();
  o.light_samples = ic.at("light_samples").get<int>();
  o.shadow_width = ic.at("shadow_width").get<int>();
  o.shadow_height = ic.at("shadow_height").get<int>();
  o.shadow_rays = ic.at("shadow_rays").get<int>();
  o.ambient = ic.at("ambient").get<double>();
  // Configs written before the key existed trained with cosine samples alone.
  o.importance_sampling = ic.value("importance_sampling", false);
  o.seed = seed;
  o.query = volume_query_options(c);
  return o;
}

RadianceQueryOptions volume_query_options(const json& c) {
  const json& v = c.at("model").at("volume");
  RadianceQueryOptions o;
  o.samples = v.at("samples").get<int>();
  SL_CHECK(o.samples >= 1, "model.volume.samples = ", o.samples, " must be >= 1");
  o.trilinear = v.at("trilinear").get<bool>();
  // Checkpoints written before the key existed sampled evenly in metres.
  const std::string spacing = v.value("spacing", std::string("metric"));
  try {
    o.spacing = parse_sample_spacing(spacing);
  } catch (const Error&) {
    throw Error("model.volume.spacing = '" + spacing + "' is not one of: metric, grid");
  }
  return o;
}

VsgGrid vsg_grid(const json& c, double camera_height_m) {
  const json& v = c.at("model").at("volume");
  VsgGrid g;
  const auto dims = v.at("dims").get<std::vector<int64_t>>();
  const auto neg = v.at("extent_neg_m").get<std::vector<double>>();
  const auto pos = v.at("extent_pos_m").get<std::vector<double>>();
  SL_CHECK(dims.size() == 3 && neg.size() == 3 && pos.size() == 3,
           "model.volume.dims / extent_neg_m / extent_pos_m must each have three entries");
  g.dims = {dims[0], dims[1], dims[2]};
  g.center = {0.0, camera_height_m, 0.0};
  g.extent_neg = {neg[0], neg[1], neg[2]};
  g.extent_pos = {pos[0], pos[1], pos[2]};
  g.log_scale_m = v.at("log_scale_m").get<double>();
  g.validate();
  return g;
}

}  // namespace sl::train
