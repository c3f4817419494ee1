// The ray file of `streetlight-bench gen-rays` / `trace --rays` (factored out of
// tools/bench/bench_trace.cpp so that it can be fuzzed, tests/fuzz).
//
// Format: no header; N rays of 6 little-endian float32 each (origin x y z, direction x y z).
// Contract: read_ray_file() accepts only a positive multiple of 24 bytes whose values are all
// finite, and returns the rays with the default tmin/tmax. It allocates the file's size plus
// N·sizeof(Ray) (32 bytes per 24-byte record). Throws sl::Error naming `what`, the file, the
// byte count or the first non-finite value (its ray index).
#pragma once
#include <string>
#include <vector>

#include "render/bvh.h"

namespace sl::render {

std::vector<Ray> read_ray_file(const std::string& path, const std::string& what = "ray file");

}  // namespace sl::render
