// Fuzz harnesses: one function per loader that parses untrusted files (issue 17).
//
// Contract: each fuzz_<target>(data, size) feeds the bytes to its loader (through a scratch
// file when the loader takes a path) and checks the loader's invariant: either it throws ONE
// sl::Error, or it returns a result that passes the loader's own validation. Anything else
// (another exception type, a failed invariant) calls violation(), which prints the target and
// the reason and aborts, so libFuzzer records the input as a crash and the corpus replay test
// (tests/fuzz/corpus_replay_test.cpp) fails. Crashes, leaks and sanitizer reports are caught
// by the sanitizers of the libFuzzer build (tests/fuzz/libfuzzer, scripts/fuzz.sh).
// The same functions serve libFuzzer (clang, ASan + UBSan) and the ordinary g++ test build.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace sl::test {

using Harness = void (*)(const uint8_t* data, size_t size);

void fuzz_safetensors(const uint8_t* data, size_t size);       // nn/safetensors, nn/checkpoint
void fuzz_gltf(const uint8_t* data, size_t size);              // render/gltf_loader (.glb and .gltf)
void fuzz_image(const uint8_t* data, size_t size);             // data/image_io read_image (EXR/HDR/PNG/JPEG)
void fuzz_kitti(const uint8_t* data, size_t size);             // data/kitti: calib text, velodyne .bin
void fuzz_calibration_json(const uint8_t* data, size_t size);  // data/kitti JSON, train/photo_input intrinsics
void fuzz_dataset(const uint8_t* data, size_t size);           // data/street_dataset index.json + sample
void fuzz_config(const uint8_t* data, size_t size);            // tools/common/config + train_config, --set
void fuzz_rays(const uint8_t* data, size_t size);              // streetlight-bench trace --rays file
void fuzz_batch_list(const uint8_t* data, size_t size);        // streetlight-insert --batch LIST.json
void fuzz_sun_labels(const uint8_t* data, size_t size);        // data/sun_labels (pano_ldr/sun_labels.csv)
void fuzz_tflite(const uint8_t* data, size_t size);            // nn/tflite parse + dequantize

struct Target {
  const char* name;  // the corpus folder: tests/fuzz/corpus/<name>/
  Harness run;
};
const std::vector<Target>& targets();

// Reports a broken invariant and aborts (libFuzzer saves the input as a crash).
[[noreturn]] void violation(const char* target, const std::string& what);

// Runs f; an sl::Error is the clean refusal, any other exception is a violation.
template <class F>
bool refuses_cleanly_or_runs(const char* target, F&& f);

// A private scratch folder for this process (created on first use, removed at exit).
const std::string& fuzz_scratch_dir();
// Writes bytes to fuzz_scratch_dir()/name (overwriting) and returns the path.
std::string write_scratch(const std::string& name, const uint8_t* data, size_t size);

}  // namespace sl::test

#include "tests/fuzz/harness/fuzz_harness_impl.h"
