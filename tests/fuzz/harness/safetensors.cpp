// Harness: nn/safetensors.h read_safetensors, and nn/checkpoint.h on the same bytes.
// Invariant: a returned file's tensors are defined, named in file_dtypes, and together hold at
// most 8x the file's bytes (the widest widening, U8 -> I64); a loaded checkpoint leaves the
// model's shapes unchanged.
#include "autodiff/tape.h"
#include "nn/checkpoint.h"
#include "nn/modules/linear.h"
#include "nn/optim.h"
#include "nn/safetensors.h"
#include "tests/fuzz/harness/fuzz_harness.h"

namespace sl::test {

void fuzz_safetensors(const uint8_t* data, size_t size) {
  const char* target = "safetensors";
  const std::string path = write_scratch("input.safetensors", data, size);
  refuses_cleanly_or_runs(target, [&] {
    const nn::SafetensorsFile f = nn::read_safetensors(path);
    uint64_t bytes = 0;
    for (const auto& [name, t] : f.tensors) {
      if (!t.defined() || !f.file_dtypes.count(name)) violation(target, "tensor '" + name + "' undefined or untyped");
      bytes += static_cast<uint64_t>(t.numel()) * dtype_size(t.dtype());
    }
    if (bytes > 8 * static_cast<uint64_t>(size))
      violation(target,
                "tensors hold " + std::to_string(bytes) + " bytes from a " + std::to_string(size) + "-byte file");
  });
  refuses_cleanly_or_runs(target, [&] { nn::read_checkpoint_info(path); });
  refuses_cleanly_or_runs(target, [&] {
    nn::Linear model(2, 3);
    nn::Adam adam(model.named_parameters(), nn::AdamOptions{});
    nn::load_checkpoint(path, model, &adam);
    const auto params = model.named_parameters();
    if (params.size() != 2 || params[0].second.shape() != Shape{3, 2})
      violation(target, "load_checkpoint changed the model's parameters");
  });
}

}  // namespace sl::test
