// Seeded parameter initialisation: Kaiming (He) and Xavier (Glorot), normal and uniform.
//
// Contract:
// - Every function fills `w` in place (under NoGradGuard) and is deterministic: element i of
//   the tensor is a pure function of (seed, name, i) through util/random.h, with the name
//   hashed to the random stream. Two parameters with different full names get independent
//   values from one seed; thread count never matters.
// - Fans follow PyTorch: for a weight [out, in, k...], fan_in = in·Πk and fan_out = out·Πk;
//   a 1-d tensor has fan_in = fan_out = its size.
// - Kaiming: std = gain / sqrt(fan), bound = gain·sqrt(3 / fan), gain = sqrt(2 / (1 + a²)) with
//   `a` the negative slope of the following leaky ReLU (0 for ReLU).
//   Xavier: std = gain·sqrt(2 / (fan_in + fan_out)), bound = gain·sqrt(6 / (fan_in + fan_out)).
// - Throws sl::Error naming the parameter for an undefined, integer or 0-d tensor where a fan
//   is needed, or for a zero fan.
// - While a SkipInitGuard lives on the calling thread, every function checks its arguments as
//   above and then leaves `w` untouched. Only for a model whose every parameter is overwritten
//   next by a strict Module::load_state_dict (which refuses a missing tensor): drawing millions of
//   normal numbers that the checkpoint replaces was a fifth of a streetlight-insert run.
#pragma once
#include <cstdint>
#include <string>
#include <utility>

#include "autodiff/tensor.h"

namespace sl::nn {

enum class FanMode { FanIn, FanOut };

// Scoped: the init functions below draw nothing on this thread while one is alive (see Contract).
class SkipInitGuard {
 public:
  SkipInitGuard();
  ~SkipInitGuard();
  SkipInitGuard(const SkipInitGuard&) = delete;
  SkipInitGuard& operator=(const SkipInitGuard&) = delete;

 private:
  bool previous_;
};
bool init_skipped();

// The random stream of a parameter name (FNV-1a, 64 bit).
uint64_t name_stream(const std::string& name);

// {fan_in, fan_out} of a weight shape.
std::pair<int64_t, int64_t> fans(const Tensor& w, const std::string& name);

void uniform_init(Tensor& w, double lo, double hi, uint64_t seed, const std::string& name);
void normal_init(Tensor& w, double mean, double stddev, uint64_t seed, const std::string& name);
void kaiming_normal_init(Tensor& w, uint64_t seed, const std::string& name, double a = 0.0,
                         FanMode mode = FanMode::FanIn);
void kaiming_uniform_init(Tensor& w, uint64_t seed, const std::string& name, double a = 0.0,
                          FanMode mode = FanMode::FanIn);
void xavier_normal_init(Tensor& w, uint64_t seed, const std::string& name, double gain = 1.0);
void xavier_uniform_init(Tensor& w, uint64_t seed, const std::string& name, double gain = 1.0);

// PyTorch's default for Linear and Conv: weight ~ U(±1/sqrt(fan_in)) (kaiming_uniform with
// a = sqrt(5)), bias ~ U(±1/sqrt(fan_in)). `bias` may be undefined.
// weight = 1 and bias = 0: the affine parameters of a normalisation layer (as PyTorch).
void norm_affine_init(Tensor& weight, Tensor& bias);

void default_layer_init(Tensor& weight, Tensor& bias, uint64_t seed, const std::string& prefix);

}  // namespace sl::nn
