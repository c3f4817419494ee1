// Reusing the samples of an earlier street-dataset render (streetlight-datagen --reuse).
//
// A sample's files are a pure function of the generator's config and the sample's index, not of
// the number of samples (data/street_generator.h, "Determinism"). So a render whose effective
// config equals this one in every key but `samples`, made by the same code, already holds this
// render's sample i whenever it holds its own sample i; only the train/val/test split, drawn over
// all ids, differs, and the caller writes its own index.json.
// - check_reusable throws sl::Error (bad input) when `source_dir` has no readable index.json, or
//   when its config differs, naming the first differing key and both values. Two strings that
//   name the same existing file or folder from the working directory (std::filesystem::equivalent:
//   "../shared/data/hdri" and its absolute path) are not a difference.
// - reuse_sample links `source_dir/samples/<id>/` into `samples_dir/<id>/`: each file hard-linked
//   (copied where the two folders are on different file systems) into a temporary sibling folder
//   that is renamed when complete (util/file.h AtomicDirectory), so a kill leaves no <id>/ behind.
//   Returns false, linking nothing, when the source's sample is missing or incomplete (no
//   meta.json). Throws sl::Error on an I/O failure, naming the file.
// Hard links share storage: a later datagen run into either folder replaces whole sample folders
// (AtomicDirectory) and never writes into a linked file.
#pragma once
#include <string>

#include <nlohmann/json.hpp>

namespace sl::data {

void check_reusable(const std::string& source_dir, const nlohmann::json& config_tree);

bool reuse_sample(const std::string& source_dir, const std::string& id, const std::string& samples_dir);

}  // namespace sl::data
