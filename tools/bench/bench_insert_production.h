// streetlight-bench insert --size kitti|nuscenes (bench_insert_production.cpp): lighting plus
// insertion of the truck into a photo at production size, one row per approximation knob, each
// with its error against a high-sample reference and its noise (bench_insert.cpp's --help has
// the flags). Prints one row per line (a JSON object each with json), and into OUT the lighting
// model it timed when no released model was found (random_default_lighting.safetensors) and,
// with bias_runs, each row's mean bias image (bias_ROW.exr).
// Throws: sl::Error naming the size or a file that cannot be read.
#pragma once
#include <string>

namespace sl::bench {

int run_production(const std::string& size, bool json, const std::string& data, const std::string& out, bool quick,
                   int reference_spp, bool reference_cache, const std::string& reference_dir, const std::string& only,
                   const std::string& lighting, int bias_runs);

}  // namespace sl::bench
