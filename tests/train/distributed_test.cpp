// train/distributed.h and train/gradient_allreduce.h in ONE process (every build, MPI or not):
// the single-process communicator is an exact no-op, so a plain run computes what it did before
// issue 18; the sharding rule and train.global_batch. The multi-rank behaviour is tested under
// mpirun in tests/distributed (MPI builds only).
#include <gtest/gtest.h>

#include "autodiff/ops.h"
#include "nn/modules/linear.h"
#include "train/distributed.h"
#include "train/gradient_allreduce.h"
#include "train/train_config.h"

namespace sl::test {
using train::Metrics;
using train::allreduce_gradients;
using train::any_rank;
using train::average_metrics;
using train::check_replicas;
using train::check_train_config;
using train::default_train_config;
using train::global_share;
using train::is_distributed;
using train::is_root;
using train::resolve_global_batch;
using train::shard_first_index;
using train::sum_over_ranks;
using train::world;

namespace {

TEST(Distributed, OneProcessIsRankZeroOfOne) {
  EXPECT_EQ(world().size(), 1);
  EXPECT_EQ(world().rank(), 0);
  EXPECT_FALSE(is_distributed());
  EXPECT_TRUE(is_root());
  EXPECT_EQ(world().backend(), "single");
}

TEST(Distributed, ShardOfOneProcessIsTheWholeBatch) {
  // Rank r of N at step s starts at (s·N + r)·b; with N = 1 that is the old s·b.
  EXPECT_EQ(shard_first_index(0, 4), 0u);
  EXPECT_EQ(shard_first_index(7, 4), 28u);
  EXPECT_EQ(global_share(0.0), 1.0);
  EXPECT_EQ(global_share(123.0), 1.0);
  EXPECT_EQ(sum_over_ranks(2.5), 2.5);
  EXPECT_TRUE(any_rank(true));
  EXPECT_FALSE(any_rank(false));
}

TEST(Distributed, SingleProcessSyncLeavesGradientsAndMetricsBitIdentical) {
  nn::Linear layer(3, 2);
  Tensor x = Tensor::uniform({4, 3}, -1, 1, 5);
  backward(mean(square(layer.forward(x))));
  const auto params = layer.named_parameters();
  std::vector<std::vector<double>> before;
  for (const auto& [n, p] : params) before.push_back(p.grad().to_vector());
  EXPECT_EQ(allreduce_gradients(params), 0.0);
  for (size_t i = 0; i < params.size(); ++i) EXPECT_EQ(params[i].second.grad().to_vector(), before[i]);
  Metrics m{{"loss", 0.1234567}, {"x", -3.0}};
  average_metrics(m, 1);
  EXPECT_EQ(m.at("loss"), 0.1234567);
  EXPECT_EQ(m.at("x"), -3.0);
  EXPECT_NO_THROW(check_replicas(layer, 1));
}

TEST(Distributed, GlobalBatchSetsThePerRankBatch) {
  nlohmann::json c = default_train_config();
  EXPECT_EQ(c["train"]["global_batch"], 0);
  resolve_global_batch(c, 2);  // 0: batch_size stays per rank
  EXPECT_EQ(c["train"]["batch_size"], 4);
  c["train"]["global_batch"] = 8;
  resolve_global_batch(c, 2);
  EXPECT_EQ(c["train"]["batch_size"], 4);
  resolve_global_batch(c, 1);
  EXPECT_EQ(c["train"]["batch_size"], 8);
  c["train"]["global_batch"] = 6;
  try {
    resolve_global_batch(c, 4);
    FAIL() << "6 samples cannot be split over 4 ranks";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("train.global_batch = 6"), std::string::npos) << e.what();
  }
  c["train"]["global_batch"] = -1;
  EXPECT_THROW(check_train_config(c), Error);
}

}  // namespace
}  // namespace sl::test
