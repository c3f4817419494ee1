// Data-parallel training (issue 18; docs/DISTRIBUTED.md): a small communicator abstraction, the
// process-wide "world" the trainer and the stages consult, and the sharding rule.
//
// Contract:
// - world() is the communicator of this process. It is a single-process no-op (rank 0 of 1)
//   unless set_world() installed another one (streetlight-train installs the MPI one of
//   train/mpi_communicator.h when it was started by mpirun). With one process every function
//   here is an exact no-op: a run computes bit for bit what it computed before issue 18.
// - Every collective (allreduce_*, broadcast, barrier) must be called by every rank in the same
//   order with the same count; the functions of this project guarantee that by calling them only
//   at points every rank reaches at the same step (never inside validation, which rank 0 alone
//   runs). abort() stops every rank of the job and does not return.
// - Sharding (global batch semantics): at step s with N ranks and a per-rank batch b, the
//   global batch is the samples s·N·b .. s·N·b + N·b − 1 of the stage's sample sequence, and
//   rank r takes the slice starting at shard_first_index(s, b) = (s·N + r)·b. Every random
//   number of a sample is a hash of (seed, global sample index) (DESIGN "Randomness"), i.e. of
//   (seed, step, rank, i): the global batch of a step is the same set of samples, drawing the
//   same random numbers, for every N with the same N·b.
// - Losses whose normaliser is a count over the batch (a masked mean) are made decomposable by
//   global_share(): a rank scales its shard's mean by share = N·max(local, 1) / max(Σ local, 1),
//   so that the mean over ranks of the scaled terms is the mean over the global batch.
#pragma once
#include <cstdint>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "train/trainer.h"

namespace sl::train {

class Communicator {
 public:
  virtual ~Communicator() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  virtual std::string backend() const = 0;  // "single" or "mpi"
  // In place: data[i] = Σ over ranks of data[i].
  virtual void allreduce_sum(float* data, int64_t count) = 0;
  virtual void allreduce_sum(double* data, int64_t count) = 0;
  // In place: data[i] = max over ranks of data[i].
  virtual void allreduce_max(double* data, int64_t count) = 0;
  // In place: every rank receives root's data.
  virtual void broadcast(float* data, int64_t count, int root) = 0;
  virtual void barrier() = 0;
  // Stops every rank of the job with `code`; never returns.
  [[noreturn]] virtual void abort(int code) = 0;
};

// The no-op communicator of one process (rank 0, size 1).
std::shared_ptr<Communicator> single_process_communicator();

Communicator& world();
void set_world(std::shared_ptr<Communicator> communicator);
inline bool is_distributed() { return world().size() > 1; }
inline bool is_root() { return world().rank() == 0; }

// train.global_batch (docs/DISTRIBUTED.md): when > 0 it must be a multiple of `world_size` and
// sets train.batch_size to global_batch / world_size; 0 keeps train.batch_size per rank (global
// batch = world_size × batch_size). The learning rate is NOT scaled: optim.lr is the rate of the
// global batch, whatever N. Throws sl::Error naming the key, the value and N.
void resolve_global_batch(nlohmann::json& config, int world_size);

// The first global sample index of this rank's shard at `step` (see the contract).
uint64_t shard_first_index(int64_t step, int64_t local_batch);

// Σ over ranks of value (value itself with one process).
double sum_over_ranks(double value);

// This rank's factor for a loss normalised by a count over the batch (see the contract); 1.0
// with one process (no collective).
double global_share(double local_count);

// Replaces every metric by its mean over ranks (so the logged loss is the global batch's);
// throws std::logic_error naming the step when the ranks report different metric names.
void average_metrics(Metrics& metrics, int64_t step);

// True on every rank when any rank's `flag` is true (a stop request seen by one rank stops all).
bool any_rank(bool flag);

}  // namespace sl::train
