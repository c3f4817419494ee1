// The world communicator, the single-process implementation and the sharding rule. See
// distributed.h; the MPI implementation is train/mpi_communicator.cpp.
#include "train/distributed.h"

#include <algorithm>
#include <cstdlib>
#include <stdexcept>
#include <vector>

#include "util/error.h"

namespace sl::train {

namespace {

class SingleProcess : public Communicator {
 public:
  int rank() const override { return 0; }
  int size() const override { return 1; }
  std::string backend() const override { return "single"; }
  void allreduce_sum(float*, int64_t) override {}
  void allreduce_sum(double*, int64_t) override {}
  void allreduce_max(double*, int64_t) override {}
  void broadcast(float*, int64_t, int) override {}
  void barrier() override {}
  [[noreturn]] void abort(int code) override { std::exit(code); }
};

std::shared_ptr<Communicator>& world_slot() {
  static std::shared_ptr<Communicator> w = single_process_communicator();
  return w;
}

// FNV-1a over the names, folded to 52 bits so that a double carries it exactly.
double names_hash(const Metrics& m) {
  uint64_t h = 1469598103934665603ULL;
  for (const auto& [k, v] : m) {
    for (unsigned char c : k) h = (h ^ c) * 1099511628211ULL;
    h = (h ^ 0xffu) * 1099511628211ULL;
  }
  return static_cast<double>(h & ((1ULL << 52) - 1));
}

}  // namespace

std::shared_ptr<Communicator> single_process_communicator() { return std::make_shared<SingleProcess>(); }

Communicator& world() { return *world_slot(); }

void set_world(std::shared_ptr<Communicator> communicator) {
  world_slot() = communicator ? std::move(communicator) : single_process_communicator();
}

void resolve_global_batch(nlohmann::json& config, int world_size) {
  nlohmann::json& t = config.at("train");
  const int64_t global = t.value("global_batch", int64_t{0});
  if (global <= 0) return;
  SL_CHECK(global % world_size == 0, "train.global_batch = ", global, " is not a multiple of the ", world_size,
           " ranks (each rank takes global_batch / ranks samples)");
  t["batch_size"] = global / world_size;
}

uint64_t shard_first_index(int64_t step, int64_t local_batch) {
  const Communicator& w = world();
  return (static_cast<uint64_t>(step) * static_cast<uint64_t>(w.size()) + static_cast<uint64_t>(w.rank())) *
         static_cast<uint64_t>(local_batch);
}

double sum_over_ranks(double value) {
  world().allreduce_sum(&value, 1);
  return value;
}

double global_share(double local_count) {
  Communicator& w = world();
  if (w.size() == 1) return 1.0;
  const double total = sum_over_ranks(local_count);
  return static_cast<double>(w.size()) * std::max(local_count, 1.0) / std::max(total, 1.0);
}

void average_metrics(Metrics& metrics, int64_t step) {
  Communicator& w = world();
  if (w.size() == 1) return;
  const double h = names_hash(metrics), n = static_cast<double>(metrics.size());
  double check[4] = {h, -h, n, -n};
  w.allreduce_max(check, 4);
  if (check[0] != -check[1] || check[2] != -check[3])  // a bug of a stage, not bad input
    throw std::logic_error(cat("data parallel: the ranks report different metric names at step ", step, " (rank ",
                               w.rank(), " has ", metrics.size(), ")"));
  std::vector<double> values;
  values.reserve(metrics.size());
  for (const auto& [k, v] : metrics) values.push_back(v);
  w.allreduce_sum(values.data(), static_cast<int64_t>(values.size()));
  size_t i = 0;
  for (auto& [k, v] : metrics) v = values[i++] / static_cast<double>(w.size());
}

bool any_rank(bool flag) {
  Communicator& w = world();
  if (w.size() == 1) return flag;
  double v = flag ? 1.0 : 0.0;
  w.allreduce_max(&v, 1);
  return v > 0;
}

}  // namespace sl::train
