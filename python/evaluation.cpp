// streetlight.evaluate: streetlight-eval (tools/eval.cpp) from Python. Both call
// tools/common/evaluation.h evaluate() with the same options, so the returned dict is the tool's
// results.json (timing fields aside, which are wall-clock), and out= writes the same files.
//
// Errors: bad option values are ValueError (check_eval_options, before any work); anything the
// evaluation raises afterwards (a missing or unreadable data folder, checkpoint, split or label
// file) is OSError, FileNotFoundError when one of the named paths does not exist. Ctrl-C stops the
// evaluation after the current image with KeyboardInterrupt.
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <pybind11/stl.h>

#include "python/bindings.h"
#include "tools/common/cli.h"
#include "tools/common/evaluation.h"

namespace sl::python {

namespace {

// None, a path (str or os.PathLike), or a sequence of paths.
std::vector<std::string> paths_of(const py::handle& obj, const char* what) {
  std::vector<std::string> out;
  if (obj.is_none()) return out;
  const py::module_ os = py::module_::import("os");
  if (py::isinstance<py::str>(obj) || py::hasattr(obj, "__fspath__")) {
    out.push_back(os.attr("fspath")(obj).cast<std::string>());
    return out;
  }
  SL_CHECK(py::isinstance<py::sequence>(obj), what, ": expected a path or a list of paths, got ",
           std::string(py::str(obj.get_type().attr("__name__"))));
  for (const py::handle item : obj) {
    SL_CHECK(py::isinstance<py::str>(item) || py::hasattr(item, "__fspath__"), what,
             ": expected paths, got an item of type ", std::string(py::str(item.get_type().attr("__name__"))));
    out.push_back(os.attr("fspath")(item).cast<std::string>());
  }
  return out;
}

std::vector<std::string> names_of(const py::handle& obj) {
  std::vector<std::string> out;
  if (obj.is_none()) return out;
  if (py::isinstance<py::str>(obj)) return {obj.cast<std::string>()};
  SL_CHECK(py::isinstance<py::sequence>(obj), "names: expected a list of strings, got ",
           std::string(py::str(obj.get_type().attr("__name__"))));
  for (const py::handle item : obj) {
    SL_CHECK(py::isinstance<py::str>(item), "names: expected strings, got an item of type ",
             std::string(py::str(item.get_type().attr("__name__"))));
    out.push_back(item.cast<std::string>());
  }
  return out;
}

std::string path_of(const py::handle& obj, const char* what) {
  const std::vector<std::string> p = paths_of(obj, what);
  SL_CHECK(p.size() <= 1, what, ": expected one path, got ", p.size());
  return p.empty() ? std::string() : p[0];
}

py::object evaluate(const py::object& checkpoints, const py::object& data, const py::object& names,
                    const std::string& split, const py::object& hdri_split, const py::object& ldr_split,
                    const py::object& sun_labels, int crops, std::optional<int64_t> limit, int view_rows,
                    const py::object& baseline_data, bool budgets, bool flip_average, bool visible_sun,
                    const std::vector<double>& crop_scales, const py::object& out) {
  cli::EvalOptions o;
  o.checkpoints = paths_of(checkpoints, "checkpoints");
  o.data = paths_of(data, "data");
  o.names = names_of(names);
  o.split = split;
  o.hdri_split = path_of(hdri_split, "hdri_split");
  o.ldr_split = path_of(ldr_split, "ldr_split");
  o.sun_labels = path_of(sun_labels, "sun_labels");
  o.crops = crops;
  SL_CHECK(!limit || *limit > 0, "limit: expected a positive count of images or None, got ", limit.value_or(0));
  o.limit = limit.value_or(0);
  o.view_rows = view_rows;
  o.baseline_data = path_of(baseline_data, "baseline_data");
  const std::string out_dir = path_of(out, "out");
  o.budgets = budgets && !out_dir.empty();  // as the tool: the sweep's plot is a file of --out
  o.flip_average = flip_average;
  o.visible_sun = visible_sun;
  // The released sun-glare detector behind the disk test, as streetlight-eval loads it by default.
  if (visible_sun) o.sun_glare = cli::released_sun_glare_path();
  o.crop_scales = crop_scales;
  cli::check_eval_options(o);  // ValueError: before any file is opened
  // Ctrl-C: checked after each image, with the GIL taken back for the check.
  o.on_image = [] {
    py::gil_scoped_acquire gil;
    if (PyErr_CheckSignals() != 0) throw py::error_already_set();
  };
  std::vector<std::string> paths = o.checkpoints;
  paths.insert(paths.end(), o.data.begin(), o.data.end());
  for (const std::string* p : {&o.hdri_split, &o.ldr_split, &o.sun_labels, &o.baseline_data}) paths.push_back(*p);
  const nlohmann::json results = file_call(paths, [&] {
    Compute c;
    cli::EvalReport r = cli::evaluate(o);
    if (!out_dir.empty()) cli::write_eval_report(r, out_dir);
    return std::move(r.results);
  });
  check_signals();
  // Through JSON text, as results.json is read: NaN is null, numbers round-trip exactly.
  return py::module_::import("json").attr("loads")(results.dump());
}

}  // namespace

void bind_evaluation(py::module_& m) {
  m.def("evaluate", &evaluate, py::arg("checkpoints") = py::none(), py::arg("data") = py::none(), py::kw_only(),
        py::arg("names") = py::none(), py::arg("split") = "test", py::arg("hdri_split") = py::none(),
        py::arg("ldr_split") = py::none(), py::arg("sun_labels") = py::none(), py::arg("crops") = 8,
        py::arg("limit") = py::none(), py::arg("view_rows") = 32, py::arg("baseline_data") = py::none(),
        py::arg("budgets") = true, py::arg("flip_average") = true, py::arg("visible_sun") = true,
        py::arg("crop_scales") = std::vector<double>{}, py::arg("out") = py::none(),
        "Evaluates checkpoints as streetlight-eval does and returns its results.json as a dict\n"
        "(docs/tools.md and tools/eval.cpp describe the metrics and keys).\n"
        "  checkpoints: a checkpoint path or a list of them (None: the released model)\n"
        "  data: a street dataset (index.json), a folder of HDR panoramas or of LDR panoramas with\n"
        "        sun_labels.csv, or a list of them; results per folder under 'datasets'\n"
        "  names: one row name per checkpoint (default: the paths); split: dataset split (test)\n"
        "  hdri_split, ldr_split: split files of panorama folders; sun_labels: the LDR labels\n"
        "  crops: perspective crops per real panorama; limit: at most this many images\n"
        "  view_rows: rows of the novel views; baseline_data: street dataset of the constant baseline\n"
        "  flip_average, visible_sun, crop_scales: the estimator's settings (--no-flip-average,\n"
        "        --no-visible-sun, --crop-scales); with visible_sun, the released sun-glare detector\n"
        "        (models/sun_glare.safetensors) backs the disk test, as in the tool\n"
        "  out: also write results.json, results.md and error_time.png there; budgets: with out, the\n"
        "        error-against-time sweep (False: --no-budgets)\n"
        "Timing fields (inference_ms, budgets' ms) are wall-clock. Bad options raise ValueError,\n"
        "missing or unreadable files OSError. Releases the GIL; Ctrl-C stops after the current image.");
}

}  // namespace sl::python
