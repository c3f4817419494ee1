// Comparison against the PyTorch 1.13 fixtures that scripts/make_torch_fixtures.py commits to
// tests/fixtures/torch/. A case `name` stores its inputs (`name.x`, `name.y`, `name.w`, `name.b`,
// `name.grid`), the output `name.out`, a fixed weight `name.R` and the gradients
// `name.grad.<input>` of sum(out · R); the JSON list of cases is the file's metadata "cases".
// run_torch_family loads each case's inputs (as leaves that require grad when the fixture holds
// their gradient), runs the op, and compares the output and every stored gradient with
// |ours − torch| ≤ 1e-4·|torch| + 1e-5·max(max|torch|, 1).
#pragma once
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <string>

#include "autodiff/ops.h"
#include "support/fixture_reader.h"

namespace sl::test {

inline std::string torch_fixture_path(const std::string& file) {
  return std::string(STREETLIGHT_SOURCE_DIR) + "/tests/fixtures/torch/" + file;
}

inline void expect_close_to_torch(const Tensor& ours, const Tensor& torch, const std::string& what) {
  ASSERT_TRUE(ours.defined()) << what << " is undefined";
  ASSERT_EQ(ours.shape(), torch.shape()) << what;
  const auto a = ours.to_vector(), b = torch.to_vector();
  double scale = 0;
  for (double v : b) scale = std::max(scale, std::abs(v));
  const double floor = 1e-5 * std::max(scale, 1.0);
  for (size_t i = 0; i < a.size(); ++i)
    ASSERT_LE(std::abs(a[i] - b[i]), 1e-4 * std::abs(b[i]) + floor)
        << what << " element " << i << ": ours " << a[i] << " vs torch " << b[i];
}

template <size_t D>
std::array<int64_t, D> json_array(const nlohmann::json& j) {
  std::array<int64_t, D> a{};
  for (size_t i = 0; i < D; ++i) a[i] = j.at(i).get<int64_t>();
  return a;
}

using TorchInputs = std::map<std::string, Tensor>;
using TorchOpFn = std::function<Tensor(const Fixture&, const std::string& name, const nlohmann::json& c, TorchInputs& in)>;

inline void run_torch_family(const std::string& file, const TorchOpFn& op) {
  const Fixture f = read_fixture(torch_fixture_path(file));
  const nlohmann::json cases = nlohmann::json::parse(f.metadata.at("cases"));
  ASSERT_FALSE(cases.empty());
  for (const nlohmann::json& c : cases) {
    const std::string name = c.at("name").get<std::string>();
    SCOPED_TRACE(name);
    TorchInputs in;
    for (const char* k : {"x", "y", "w", "b", "grid"}) {
      const std::string key = name + "." + k;
      if (f.has(key)) {
        in[k] = f.at(key).clone();
        if (f.has(name + ".grad." + k)) in[k].set_requires_grad(true);
      }
    }
    Tensor out = op(f, name, c, in);
    expect_close_to_torch(out, f.at(name + ".out"), name + ".out");
    backward(out, f.at(name + ".R"));
    for (const auto& [k, t] : in)
      if (f.has(name + ".grad." + k)) expect_close_to_torch(t.grad(), f.at(name + ".grad." + k), name + ".grad." + k);
  }
}

inline Tensor optional_input(const TorchInputs& in, const char* k) {
  auto it = in.find(k);
  return it == in.end() ? Tensor() : it->second;
}

}  // namespace sl::test
