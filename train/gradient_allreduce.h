// The data-parallel step (issue 18, docs/DISTRIBUTED.md): every rank computed the gradients of
// its shard; allreduce_gradients() replaces each by the mean over ranks, so that every rank's
// optimiser takes the same step (the PyTorch DDP scheme). Plus the replica bookkeeping around it.
//
// Contract:
// - allreduce_gradients(params): collective. A parameter whose gradient is undefined on every
//   rank stays undefined (the optimiser skips it, as in one process); one with a gradient on
//   some rank gets the mean over ALL ranks, a rank without one counting zeros. float32
//   gradients travel in buckets of kAllReduceBucketBytes (one MPI_Allreduce per bucket, in
//   parameter order), float64 ones one parameter at a time. Returns the wall time in ms,
//   waiting for the slowest rank included. With one process: no-op, returns 0.
//   No overlap with the backward pass: the tape runs backward as one call and offers no hook
//   when a leaf's gradient is final, and on these machines each rank's only core computes both;
//   docs/DISTRIBUTED.md measures the all-reduce's share of the step instead.
// - broadcast_parameters / broadcast_buffers(module): collective; every rank receives rank 0's
//   values (float32 tensors; others are checked to be equal by check_replicas).
// - Batch normalisation: PER-RANK statistics. A BatchNorm layer normalises each rank's shard
//   with that shard's own mean and variance (not the global batch's), and after each step the
//   running statistics of rank 0 are broadcast (broadcast_buffers), so every replica and the
//   checkpoint hold rank 0's. The paper's models use group and instance norm, which have no
//   cross-sample statistics, so they are unaffected (tests/distributed show both).
// - check_replicas(module, step): collective; throws std::runtime_error naming the first
//   parameter or buffer whose bytes differ between ranks (a bug, not bad input).
#pragma once
#include <cstdint>

#include "nn/module.h"

namespace sl::train {

inline constexpr int64_t kAllReduceBucketBytes = 8 << 20;

double allreduce_gradients(const nn::NamedTensors& params);
void broadcast_parameters(nn::Module& module);
void broadcast_buffers(nn::Module& module);
void check_replicas(const nn::Module& module, int64_t step);

}  // namespace sl::train
