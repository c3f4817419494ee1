// streetlight-datagen: renders the synthetic street-scene dataset (data/street_generator.h,
// format in docs/DATASET.md). Bad flags or config values exit 2; a failure while rendering or
// writing exits 1. Progress on stderr; with --json one summary object on stdout.
#include <omp.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "data/contact_sheet.h"
#include "data/sample_reuse.h"
#include "data/street_dataset.h"
#include "data/street_generator.h"
#include "tools/common/cli.h"
#include "util/file.h"
#include "tools/common/config.h"
#include "util/error.h"

namespace {

namespace fs = std::filesystem;

int run(int argc, char** argv) {
  sl::cli::Args args(
      "streetlight-datagen",
      "--out DIR [--config FILE.json] [--set key=value ...] [--samples N] [--json]\n\n"
      "Renders procedural street scenes with the reference path tracer: per sample an HDR/LDR panorama with\n"
      "sky mask and sun direction, perspective views with depth, the true HDR sky and an object-insertion\n"
      "pair. Writes DIR/index.json and DIR/samples/<id>/ (docs/DATASET.md). The same seed gives the same files.",
      {{"--out", "DIR", "output folder (created; existing samples of the same ids are replaced)"},
       {"--config", "FILE", "JSON config; every key is optional (defaults: see --print-config)"},
       {"--set", "KEY=VALUE", "override one config key, e.g. --set views.count=3", true},
       {"--samples", "N", "number of samples (overrides 'samples')"},
       {"--shard", "K/N", "render only the samples i with i mod N = K (run N processes on one --out)"},
       {"--skip-existing", "", "keep samples already complete in DIR (samples/<id>/meta.json exists)"},
       {"--reuse", "SRC", "link the samples an earlier render SRC holds instead of rendering them (same config but 'samples')"},
       {"--contact-sheet", "PNG", "also write a contact sheet of the first rows to this PNG"},
       {"--contact-rows", "N", "rows of the contact sheet (default 4)"},
       {"--print-config", "", "print the effective config as JSON and exit"},
       {"--json", "", "print a machine-readable summary on stdout"}});
  if (!args.parse(argc, argv)) return 0;

  sl::cli::Config config(sl::data::street_generator_defaults());
  if (args.has("--config")) config.merge_file(args.get("--config"));
  for (const std::string& s : args.all("--set")) config.set(s);
  if (args.has("--samples")) config.set("samples=" + std::to_string(args.integer("--samples", 0)));
  if (args.has("--print-config")) {
    std::cout << config.tree().dump(2) << "\n";
    return 0;
  }
  SL_CHECK(args.has("--out"), "streetlight-datagen: --out DIR is required; try --help");
  const sl::data::StreetGeneratorConfig c = sl::data::street_generator_config(config.tree());
  const std::string out = args.get("--out");
  const int contact_rows = static_cast<int>(args.integer("--contact-rows", 4));
  int64_t shard = 0, shards = 1;
  if (args.has("--shard")) {
    const std::string v = args.get("--shard");
    const auto slash = v.find('/');
    try {
      SL_CHECK(slash != std::string::npos, "");
      shard = std::stoll(v.substr(0, slash));
      shards = std::stoll(v.substr(slash + 1));
    } catch (const std::exception&) {
      sl::fail("--shard expects K/N (e.g. 0/2), got '", v, "'");
    }
    SL_CHECK(shards >= 1 && shard >= 0 && shard < shards, "--shard K/N needs 0 <= K < N, got '", v, "'");
  }
  SL_CHECK(contact_rows >= 1 && contact_rows <= 64, "--contact-rows must be in [1, 64], got ", contact_rows);
  const std::string reuse = args.has("--reuse") ? args.get("--reuse") : std::string();
  if (!reuse.empty()) {
    std::error_code ec;
    SL_CHECK(!fs::exists(out, ec) || !fs::equivalent(reuse, out, ec), "--reuse '", reuse, "' is the --out folder itself");
    sl::data::check_reusable(reuse, c.tree);
  }

  // From here on every failure is a run-time failure (exit 1), not bad input.
  try {
    const fs::path samples_dir = fs::path(out) / "samples";
    fs::create_directories(samples_dir);
    sl::sweep_stale_temp_files(samples_dir.string());  // what a killed run left (live processes keep theirs)
    const auto t0 = std::chrono::steady_clock::now();
    sl::cli::Progress progress("datagen", c.samples);
    std::vector<std::string> ids;
    int64_t with_object = 0;
    int64_t rendered = 0, reused = 0;
    for (int64_t i = 0; i < c.samples; ++i) {
      char id[32];
      std::snprintf(id, sizeof id, "%06lld", static_cast<long long>(i));  // docs/DATASET.md ids
      ids.push_back(id);
      const bool mine = i % shards == shard;
      if (!mine || (args.has("--skip-existing") && fs::exists(samples_dir / id / "meta.json"))) continue;
      if (!reuse.empty() && sl::data::reuse_sample(reuse, id, samples_dir.string())) {
        ++reused;
        // The summary's with_object counts every sample of this run, linked ones too.
        const nlohmann::json meta = sl::data::read_json(samples_dir / id / "meta.json", "--reuse sample " + ids.back());
        with_object += meta.contains("object") && !meta["object"].is_null() ? 1 : 0;
        progress.update(i + 1, "sample " + ids.back() + " (reused)");
        continue;
      }
      const sl::data::GeneratedSample g = sl::data::generate_street_sample(c, i, samples_dir.string());
      SL_CHECK(g.id == ids.back(), "datagen: sample ", i, " has id '", g.id, "', expected '", ids.back(), "'");
      with_object += g.has_insertion ? 1 : 0;
      ++rendered;
      progress.update(i + 1, "sample " + g.id);
    }
    progress.finish();
    // The index depends only on the config (a seeded split of all ids), so every shard writes
    // the same file; it is complete once every shard has finished.
    sl::data::write_dataset_index(out, c, sl::data::split_ids(ids, c.seed, c.train_fraction, c.val_fraction));
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (args.has("--contact-sheet")) sl::data::write_contact_sheet(out, args.get("--contact-sheet"), contact_rows);
    const nlohmann::json summary = {{"out", out},
                                    {"samples", c.samples},
                                    {"rendered", rendered},
                                    {"reused", reused},
                                    {"with_object", with_object},
                                    {"seconds", seconds},
                                    {"samples_per_minute", seconds > 0 ? 60.0 * static_cast<double>(rendered) / seconds : 0.0},
                                    {"threads", omp_get_max_threads()}};
    if (args.has("--json"))
      std::cout << summary.dump() << "\n";
    else
      std::fprintf(stderr, "wrote %lld samples to %s in %.1f s (%.2f samples/min, %d threads)%s\n",
                   static_cast<long long>(rendered), out.c_str(), seconds, summary["samples_per_minute"].get<double>(),
                   omp_get_max_threads(),
                   reused > 0 ? (", " + std::to_string(reused) + " reused from " + reuse).c_str() : "");
  } catch (const std::exception& e) {
    throw std::runtime_error(e.what());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return sl::cli::run_main([&] { return run(argc, argv); });
}
