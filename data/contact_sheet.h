// A contact sheet of generated street samples (docs/), composed from the dataset's own files so
// a reader sees what the data looks like: per row, the LDR panorama, each view's LDR and
// depth (near = bright, sky = black), and the insertion pair without / with the object.
//
// Requires: a dataset folder written by the generator (docs/DATASET.md). Tiles are resized
// by nearest neighbour to a common height; the sheet is 8-bit RGB PNG.
// Throws: sl::Error naming the sample folder or file that cannot be read or written.
#pragma once
#include <string>
#include <vector>

#include "autodiff/tensor.h"

namespace sl::data {

// [3, H, W] in [0, 1]; `rows` samples (in index order) from `dataset_dir`.
Tensor compose_contact_sheet(const std::string& dataset_dir, int rows, int tile_height = 96);
void write_contact_sheet(const std::string& dataset_dir, const std::string& png_path, int rows,
                         int tile_height = 96);

}  // namespace sl::data
