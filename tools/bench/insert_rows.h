// The rows of streetlight-bench insert's production table (--size kitti|nuscenes): the
// production settings (train/photo_insertion.h, what streetlight-insert runs by default) and,
// unless quick, one variant per approximation knob — the control variate, the probe grids,
// adaptive sampling, the residual filter, exact volume queries, sample counts — so each knob's
// error is printed against its run time (--rows picks rows by name).
#pragma once
#include <string>
#include <vector>

#include "render/object_insertion.h"
#include "train/photo_insertion.h"

namespace sl::bench {

struct InsertRow {
  std::string name;
  render::InsertionOptions opt;
};

std::vector<InsertRow> insert_rows(const train::PhotoInsertionOptions& production, bool quick);

}  // namespace sl::bench
