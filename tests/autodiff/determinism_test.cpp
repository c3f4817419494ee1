// Elementwise ops, reductions and matmul give bitwise identical results with 1 and 2 threads.
#include <gtest/gtest.h>
#include <omp.h>

#include "autodiff/ops.h"
#include "support/test_util.h"

namespace sl::test {
namespace {

struct Outputs {
  std::vector<double> values, grad;
};

Outputs run_workload(int threads) {
  const int saved = omp_get_max_threads();
  omp_set_num_threads(threads);
  // Large enough that every op takes its parallel path (several chunks and reduce blocks).
  Tensor x = Tensor::uniform({512, 1024}, -2, 2, 1, DType::F32).set_requires_grad(true);
  Tensor w = Tensor::uniform({1024, 300}, -0.05, 0.05, 2, DType::F32).set_requires_grad(true);
  Tensor h = tanh(matmul(x, w));
  Tensor e = add(mul(exp(mul_scalar(x, 0.5)), sigmoid(x)), softplus(x));
  Tensor loss = add(add(sum(h), mean(square(e))), sum(logsumexp(e, 1)));
  Tensor partial = sum(e, {0});
  Outputs o;
  o.values = partial.to_vector();
  o.values.push_back(loss.item());
  backward(loss);
  o.grad = x.grad().to_vector();
  const auto gw = w.grad().to_vector();
  o.grad.insert(o.grad.end(), gw.begin(), gw.end());
  omp_set_num_threads(saved);
  return o;
}

TEST(Determinism, BitwiseIdenticalWithOneAndTwoThreads) {
  const Outputs one = run_workload(1), two = run_workload(2);
  ASSERT_EQ(one.values.size(), two.values.size());
  for (size_t i = 0; i < one.values.size(); ++i) ASSERT_EQ(one.values[i], two.values[i]) << "value " << i;
  ASSERT_EQ(one.grad.size(), two.grad.size());
  for (size_t i = 0; i < one.grad.size(); ++i) ASSERT_EQ(one.grad[i], two.grad[i]) << "grad " << i;
}

TEST(Determinism, FullReductionMatchesAcrossThreadCountsOnHugeInput) {
  Tensor t = Tensor::normal({3 << 20}, 0, 1, 7, DType::F32);
  omp_set_num_threads(1);
  const double a = sum(t).item();
  omp_set_num_threads(2);
  const double b = sum(t).item();
  EXPECT_EQ(a, b);
}

}  // namespace
}  // namespace sl::test
