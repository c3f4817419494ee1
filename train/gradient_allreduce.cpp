// Bucketed gradient all-reduce and replica bookkeeping. See gradient_allreduce.h.
#include "train/gradient_allreduce.h"

#include <chrono>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "train/distributed.h"

namespace sl::train {

namespace {

// A contiguous float32 gradient of p (zeros when p has none here).
Tensor local_grad_f32(const Tensor& p) {
  if (!p.grad().defined()) return Tensor::zeros(p.shape(), DType::F32);
  const Tensor g = p.grad().dtype() == DType::F32 ? p.grad().contiguous() : p.grad().to(DType::F32).contiguous();
  return g;
}

void reduce_bucket(std::vector<float>& bucket, const std::vector<std::pair<Tensor, int64_t>>& members) {
  Communicator& w = world();
  w.allreduce_sum(bucket.data(), static_cast<int64_t>(bucket.size()));
  const float inv = 1.0f / static_cast<float>(w.size());
  for (const auto& [p, offset] : members) {
    // Into the gradient's own memory when it is a plain float32 buffer (no allocation per step).
    const Tensor& own = p.grad();
    const bool in_place = own.defined() && own.dtype() == DType::F32 && own.is_contiguous();
    Tensor g = in_place ? own : Tensor::empty(p.shape(), DType::F32);
    float* d = g.data<float>();
    const float* s = bucket.data() + offset;
    const int64_t n = g.numel();  // once: numel() walks the shape on every call
    for (int64_t i = 0; i < n; ++i) d[i] = s[i] * inv;
    if (!in_place) const_cast<Tensor&>(p).set_grad(p.dtype() == DType::F32 ? g : g.to(p.dtype()));
  }
  bucket.clear();
}

// Visits every float tensor of `tensors` as contiguous bytes.
template <class F>
void for_each_f32(const nn::NamedTensors& tensors, F&& f) {
  for (const auto& [name, t] : tensors)
    if (t.dtype() == DType::F32) f(name, t);
}

}  // namespace

double allreduce_gradients(const nn::NamedTensors& params) {
  Communicator& w = world();
  if (w.size() == 1) return 0.0;
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<double> present(params.size());
  for (size_t i = 0; i < params.size(); ++i) present[i] = params[i].second.grad().defined() ? 1.0 : 0.0;
  w.allreduce_max(present.data(), static_cast<int64_t>(present.size()));
  std::vector<float> bucket;
  std::vector<std::pair<Tensor, int64_t>> members;
  const size_t bucket_floats = static_cast<size_t>(kAllReduceBucketBytes) / sizeof(float);
  for (size_t i = 0; i < params.size(); ++i) {
    if (present[i] == 0.0) continue;
    const Tensor& p = params[i].second;
    if (p.dtype() == DType::F64) {  // gradient checks and float64 runs: exact, one at a time
      Tensor g = p.grad().defined() ? p.grad().contiguous().clone() : Tensor::zeros(p.shape(), DType::F64);
      w.allreduce_sum(g.data<double>(), g.numel());
      double* d = g.data<double>();
      const int64_t n = g.numel();
      for (int64_t k = 0; k < n; ++k) d[k] /= static_cast<double>(w.size());
      const_cast<Tensor&>(p).set_grad(g);
      continue;
    }
    const Tensor g = local_grad_f32(p);
    if (!bucket.empty() && bucket.size() + static_cast<size_t>(g.numel()) > bucket_floats) {
      reduce_bucket(bucket, members);
      members.clear();
    }
    members.emplace_back(p, static_cast<int64_t>(bucket.size()));
    bucket.insert(bucket.end(), g.data<float>(), g.data<float>() + g.numel());
  }
  if (!bucket.empty()) reduce_bucket(bucket, members);
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void broadcast_parameters(nn::Module& module) {
  if (!is_distributed()) return;
  for_each_f32(module.named_parameters(), [](const std::string&, const Tensor& t) {
    Tensor c = t.contiguous();
    world().broadcast(c.data<float>(), c.numel(), 0);
    if (c.raw_data() != t.raw_data()) const_cast<Tensor&>(t).copy_(c);
  });
}

void broadcast_buffers(nn::Module& module) {
  if (!is_distributed()) return;
  for_each_f32(module.named_buffers(), [](const std::string&, const Tensor& t) {
    Tensor c = t.contiguous();
    world().broadcast(c.data<float>(), c.numel(), 0);
    if (c.raw_data() != t.raw_data()) const_cast<Tensor&>(t).copy_(c);
  });
}

void check_replicas(const nn::Module& module, int64_t step) {
  Communicator& w = world();
  if (w.size() == 1) return;
  std::vector<std::string> names;
  std::vector<double> hashes;  // (h, −h) per tensor: max over ranks of both is (h, −h) iff all agree
  auto add = [&](const nn::NamedTensors& tensors, const char* kind) {
    for (const auto& [name, t] : tensors) {
      const Tensor c = t.contiguous();
      const auto* bytes = static_cast<const unsigned char*>(c.raw_data());
      const size_t n = static_cast<size_t>(c.numel()) * dtype_size(c.dtype());
      uint64_t h = 1469598103934665603ULL;
      for (size_t i = 0; i < n; ++i) h = (h ^ bytes[i]) * 1099511628211ULL;
      const double v = static_cast<double>(h & ((1ULL << 52) - 1));
      names.push_back(cat(kind, " '", name, "'"));
      hashes.insert(hashes.end(), {v, -v});
    }
  };
  add(module.named_parameters(), "parameter");
  add(module.named_buffers(), "buffer");
  double count[2] = {static_cast<double>(names.size()), -static_cast<double>(names.size())};
  w.allreduce_max(count, 2);
  if (count[0] != -count[1])
    throw std::runtime_error(cat("data parallel: the ranks hold models of different sizes at step ", step));
  w.allreduce_max(hashes.data(), static_cast<int64_t>(hashes.size()));
  for (size_t i = 0; i < names.size(); ++i)
    if (hashes[2 * i] != -hashes[2 * i + 1])
      throw std::runtime_error(cat("data parallel: ", names[i], " differs between ranks at step ", step,
                                   " (the replicas diverged; this is a bug)"));
}

}  // namespace sl::train
