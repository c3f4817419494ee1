// Module system: names, state dicts, modes, freezing, initialisation.
#include <gtest/gtest.h>

#include <cmath>

#include "autodiff/gradcheck.h"
#include "autodiff/ops.h"
#include "nn/init.h"
#include "nn/module.h"
#include "nn/modules/activations.h"
#include "nn/modules/batch_norm.h"
#include "nn/modules/group_norm.h"
#include "nn/modules/layer_norm.h"
#include "nn/modules/linear.h"
#include "nn/modules/mlp.h"

namespace sl::test {
using nn::BatchNorm2d;
using nn::FanMode;
using nn::GroupNorm;
using nn::LeakyReLU;
using nn::LayerNorm;
using nn::Linear;
using nn::MLP;
using nn::Module;
using nn::ModuleList;
using nn::NamedTensors;
using nn::ReLU;
using nn::Sequential;
using nn::Sigmoid;
using nn::StateDict;
using nn::kaiming_normal_init;
using nn::init_skipped;
using nn::kaiming_uniform_init;
using nn::normal_init;
using nn::SkipInitGuard;
using nn::uniform_init;
using nn::make_activation;
using nn::xavier_normal_init;
using nn::xavier_uniform_init;

namespace {

// A toy block shaped like torchvision's BasicBlock naming: conv1-like Linear, a ModuleList.
class Block : public Module {
 public:
  Block() : Module("Block") {
    register_parameter("scale", Tensor::ones({2}));
    register_buffer("count", Tensor::zeros({}, DType::I64));
    fc1 = register_module("fc1", std::make_shared<Linear>(2, 3));
    auto list = std::make_shared<ModuleList>();
    list->push_back(std::make_shared<Linear>(3, 3));
    list->push_back(std::make_shared<ReLU>());
    list->push_back(std::make_shared<Linear>(3, 2, false));
    layers = register_module("layers", list);
  }
  std::shared_ptr<Linear> fc1;
  std::shared_ptr<ModuleList> layers;
};

std::vector<std::string> names_of(const NamedTensors& list) {
  std::vector<std::string> out;
  for (const auto& [n, t] : list) out.push_back(n);
  return out;
}

TEST(Module, NamesAreHierarchicalInRegistrationOrder) {
  auto root = std::make_shared<Sequential>();
  root->push_back(std::make_shared<Block>());
  root->push_back(std::make_shared<Block>());
  const auto names = names_of(root->named_parameters());
  const std::vector<std::string> expected = {
      "0.scale", "0.fc1.weight", "0.fc1.bias", "0.layers.0.weight", "0.layers.0.bias", "0.layers.2.weight",
      "1.scale", "1.fc1.weight", "1.fc1.bias", "1.layers.0.weight", "1.layers.0.bias", "1.layers.2.weight"};
  EXPECT_EQ(names, expected);
  EXPECT_EQ(names_of(root->named_buffers()), (std::vector<std::string>{"0.count", "1.count"}));
  EXPECT_EQ(root->state_dict().size(), expected.size() + 2);
  const auto mods = root->named_modules();
  EXPECT_EQ(mods[0].first, "");
  EXPECT_EQ(mods[1].first, "0");
  EXPECT_EQ(mods[2].first, "0.fc1");
  EXPECT_EQ(mods[4].first, "0.layers.0");
}

TEST(Module, DuplicateOrDottedNamesThrowNamingTheMember) {
  Block b;
  try {
    b.register_parameter("scale", Tensor::zeros({1}));
    FAIL() << "expected a throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'scale' is already registered"), std::string::npos) << e.what();
  }
  EXPECT_THROW(b.register_buffer("a.b", Tensor::zeros({1})), Error);
  EXPECT_THROW(b.register_module("fc1", std::make_shared<ReLU>()), Error);
  EXPECT_THROW(b.parameter("nope"), Error);
}

TEST(Module, ParameterCountCountsAllOrOnlyTrainable) {
  Block b;
  const int64_t total = 2 + (2 * 3 + 3) + (3 * 3 + 3) + 3 * 2;
  EXPECT_EQ(b.parameter_count(), total);
  b.fc1->freeze();
  EXPECT_EQ(b.parameter_count(), total);
  EXPECT_EQ(b.parameter_count(true), total - 9);
}

TEST(Module, TrainAndEvalAreRecursive) {
  Block b;
  EXPECT_TRUE(b.layers->children()[1].second->is_training());
  b.eval();
  for (auto& [name, m] : b.named_modules()) EXPECT_FALSE(m->is_training()) << name;
  b.train();
  for (auto& [name, m] : b.named_modules()) EXPECT_TRUE(m->is_training()) << name;
}

TEST(Module, LoadStateDictCopiesInPlaceSoHandlesStayValid) {
  Block a, b;
  b.init_parameters(7);
  const Tensor handle = a.fc1->parameter("weight");
  a.load_state_dict(b.state_dict());
  EXPECT_EQ(handle.to_vector(), b.fc1->parameter("weight").to_vector());
  EXPECT_TRUE(a.fc1->parameter("weight").same(handle));
  EXPECT_FALSE(handle.same(b.fc1->parameter("weight")));  // a copy, not shared
}

TEST(Module, LoadStateDictListsMissingUnexpectedAndMismatchedInOneMessage) {
  Block a;
  StateDict s = a.state_dict();
  const std::vector<double> before = a.parameter("scale").to_vector();
  s.erase("fc1.bias");
  s["extra.weight"] = Tensor::zeros({1});
  s["fc1.weight"] = Tensor::zeros({4, 4});
  s["scale"] = Tensor::full({2}, 5.0, DType::F64);
  try {
    a.load_state_dict(s);
    FAIL() << "expected a throw";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("1 missing: fc1.bias"), std::string::npos) << msg;
    EXPECT_NE(msg.find("1 unexpected: extra.weight"), std::string::npos) << msg;
    EXPECT_NE(msg.find("fc1.weight: expected f32[3, 2], got f32[4, 4]"), std::string::npos) << msg;
    EXPECT_NE(msg.find("scale: expected f32[2], got f64[2]"), std::string::npos) << msg;
  }
  EXPECT_EQ(a.parameter("scale").to_vector(), before);  // nothing was copied
}

TEST(Module, AMismatchOfManyTensorsNamesTheFirstFiveAndCountsTheRest) {
  nn::StateMismatch m;
  for (int i = 0; i < 12; ++i) m.mismatched.push_back(cat("layer", i, ".weight: expected f32[4], got f32[2]"));
  m.missing = {"a", "b"};
  const std::string msg = m.message();
  EXPECT_NE(msg.find("12 mismatched: layer0.weight"), std::string::npos) << msg;
  EXPECT_NE(msg.find("layer4.weight: expected f32[4], got f32[2], ... and 7 more"), std::string::npos) << msg;
  EXPECT_EQ(msg.find("layer5.weight"), std::string::npos) << msg;
  EXPECT_NE(msg.find("2 missing: a, b"), std::string::npos) << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  EXPECT_EQ(m.mismatched.size(), 12u);  // the lists themselves stay whole
}

TEST(Module, FrozenModuleGetsNoGradientYetPassesGradientToItsInput) {
  // y = frozen(trainable(x)): the paper's frozen sky decoder sits after trainable layers.
  auto trainable = std::make_shared<Linear>(3, 4);
  auto frozen = std::make_shared<Linear>(4, 2);
  Sequential net({trainable, frozen});
  net.init_parameters(3);
  Tensor x = Tensor::uniform({5, 3}, -1, 1, 11).set_requires_grad(true);

  backward(sum(square(net.forward(x))));
  const std::vector<double> x_grad_unfrozen = x.grad().to_vector();
  const std::vector<double> w_grad_unfrozen = trainable->parameter("weight").grad().to_vector();
  net.zero_grad();
  x.zero_grad();

  frozen->freeze();
  EXPECT_TRUE(frozen->is_frozen());
  EXPECT_FALSE(frozen->parameter("weight").requires_grad());
  backward(sum(square(net.forward(x))));
  EXPECT_FALSE(frozen->parameter("weight").grad().defined());
  EXPECT_FALSE(frozen->parameter("bias").grad().defined());
  ASSERT_TRUE(trainable->parameter("weight").grad().defined());
  ASSERT_TRUE(x.grad().defined());
  EXPECT_EQ(trainable->parameter("weight").grad().to_vector(), w_grad_unfrozen);
  EXPECT_EQ(x.grad().to_vector(), x_grad_unfrozen);

  frozen->freeze(false);
  EXPECT_TRUE(frozen->parameter("weight").requires_grad());
}

TEST(Module, FreezingTheWholeModelStillGivesTheInputAGradient) {
  MLP mlp({.widths = {2, 8, 1}, .activation = "tanh", .seed = 1});
  mlp.freeze();
  Tensor x = Tensor::uniform({4, 2}, -1, 1, 5).set_requires_grad(true);
  backward(sum(mlp.forward(x)));
  ASSERT_TRUE(x.grad().defined());
  for (auto& [name, p] : mlp.named_parameters()) EXPECT_FALSE(p.grad().defined()) << name;
}

TEST(Module, ZeroGradDropsEveryGradient) {
  Block b;
  Tensor x = Tensor::uniform({1, 2}, -1, 1, 2);
  backward(sum(b.layers->children()[2].second->forward(b.layers->children()[0].second->forward(b.fc1->forward(x)))));
  EXPECT_TRUE(b.fc1->parameter("weight").grad().defined());
  b.zero_grad();
  for (auto& [name, p] : b.named_parameters()) EXPECT_FALSE(p.grad().defined()) << name;
}

TEST(Module, ToF64ConvertsParametersKeepsValuesAndTrainability) {
  MLP mlp({.widths = {3, 4, 2}, .seed = 9});
  const std::vector<double> before = mlp.named_parameters()[0].second.to_vector();
  mlp.to(DType::F64);
  for (auto& [name, p] : mlp.named_parameters()) {
    EXPECT_EQ(p.dtype(), DType::F64) << name;
    EXPECT_TRUE(p.requires_grad()) << name;
  }
  EXPECT_EQ(mlp.named_parameters()[0].second.to_vector(), before);
}

// A Sequential lets a normalisation absorb the ReLU / LeakyReLU after it: one tape node fewer,
// the same bits as running the modules one by one. Other neighbours (a negative slope, a
// sigmoid) are left as they are.
TEST(Sequential, NormFollowedByActivationRunsAsOneOpWithTheSameResult) {
  const Tensor x = Tensor::uniform({2, 4, 3, 5}, -2, 2, 3);
  auto run = [&](std::shared_ptr<Module> norm, std::shared_ptr<Module> act, bool expect_fused) {
    Sequential seq({norm, act});
    Tensor xa = x.clone().set_requires_grad(true), xb = x.clone().set_requires_grad(true);
    const size_t before = tape_size();
    const Tensor fused = seq.forward(xa);
    const size_t nodes = tape_size() - before;
    const Tensor unfused = act->forward(norm->forward(xb));
    EXPECT_EQ(nodes, expect_fused ? 1u : 2u) << norm->type_name() << " + " << act->type_name();
    backward(sum(mul(fused, x)));
    backward(sum(mul(unfused, x)));
    EXPECT_EQ(fused.to_vector(), unfused.to_vector());
    EXPECT_EQ(xa.grad().to_vector(), xb.grad().to_vector());
  };
  run(std::make_shared<GroupNorm>(2, 4), std::make_shared<LeakyReLU>(0.2), true);
  run(std::make_shared<BatchNorm2d>(4), std::make_shared<ReLU>(), true);
  run(std::make_shared<GroupNorm>(2, 4), std::make_shared<LeakyReLU>(-0.5), false);
  run(std::make_shared<BatchNorm2d>(4), std::make_shared<Sigmoid>(), false);
}

TEST(Module, DefaultForwardThrowsNamingTheType) {
  Block b;
  try {
    b.forward(Tensor::zeros({1}));
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("Block"), std::string::npos);
  }
}

// ---------------------------------------------------------------- initialisation
class Pair : public Module {
 public:
  explicit Pair(bool with_extra) : Module("Pair") {
    register_module("a", std::make_shared<Linear>(4, 4));
    if (with_extra) register_module("extra", std::make_shared<Linear>(4, 4));
    register_module("b", std::make_shared<Linear>(4, 4));
  }
};

TEST(Init, ValuesDependOnlyOnSeedAndFullName) {
  Pair p(false), q(true);
  p.init_parameters(42);
  q.init_parameters(42);
  EXPECT_EQ(p.child("b")->parameter("weight").to_vector(), q.child("b")->parameter("weight").to_vector());
  EXPECT_NE(p.child("a")->parameter("weight").to_vector(), p.child("b")->parameter("weight").to_vector());
  Pair r(false);
  r.init_parameters(43);
  EXPECT_NE(p.child("a")->parameter("weight").to_vector(), r.child("a")->parameter("weight").to_vector());
}

double stddev_of(const Tensor& t) {
  const auto v = t.to_vector();
  double m = 0, s = 0;
  for (double x : v) m += x;
  m /= double(v.size());
  for (double x : v) s += (x - m) * (x - m);
  return std::sqrt(s / double(v.size()));
}

TEST(Init, KaimingAndXavierHaveTheirDocumentedScale) {
  Tensor w = Tensor::empty({128, 64, 3, 3});  // fan_in 576, fan_out 1152
  kaiming_normal_init(w, 1, "w");
  EXPECT_NEAR(stddev_of(w), std::sqrt(2.0 / 576), 0.02 * std::sqrt(2.0 / 576));
  kaiming_normal_init(w, 1, "w", 0.0, FanMode::FanOut);
  EXPECT_NEAR(stddev_of(w), std::sqrt(2.0 / 1152), 0.02 * std::sqrt(2.0 / 1152));
  kaiming_uniform_init(w, 1, "w");
  const double bound = std::sqrt(6.0 / 576);
  double mx = 0;
  for (double v : w.to_vector()) mx = std::max(mx, std::abs(v));
  EXPECT_LE(mx, bound);
  EXPECT_GT(mx, 0.99 * bound);
  EXPECT_NEAR(stddev_of(w), bound / std::sqrt(3.0), 0.02 * bound);
  xavier_normal_init(w, 1, "w");
  EXPECT_NEAR(stddev_of(w), std::sqrt(2.0 / (576 + 1152)), 0.02 * std::sqrt(2.0 / (576 + 1152)));
  xavier_uniform_init(w, 1, "w", 2.0);
  EXPECT_NEAR(stddev_of(w), 2.0 * std::sqrt(2.0 / (576 + 1152)), 0.04 * std::sqrt(2.0 / (576 + 1152)));
}

TEST(Init, ZeroFanOrIntegerTensorThrowsNamingTheParameter) {
  Tensor w = Tensor::empty({0, 3});
  EXPECT_THROW(kaiming_normal_init(w, 0, "conv.weight", 0.0, FanMode::FanOut), Error);
  Tensor i = Tensor::zeros({3, 3}, DType::I64);
  try {
    xavier_uniform_init(i, 0, "conv.weight");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("conv.weight"), std::string::npos);
  }
}

// For a model loaded next (train/inference.cpp): nothing is drawn, the checks still run, and the
// guard restores the previous state when it ends, nested or not.
TEST(Init, SkipInitGuardDrawsNothingStillChecksAndRestores) {
  Tensor w = Tensor::full({4, 3}, 7.0);
  {
    const SkipInitGuard outer;
    {
      const SkipInitGuard inner;
      EXPECT_TRUE(init_skipped());
    }
    EXPECT_TRUE(init_skipped());
    kaiming_normal_init(w, 1, "conv.weight");
    normal_init(w, 0.0, 1.0, 1, "conv.weight");
    uniform_init(w, -1.0, 1.0, 1, "conv.weight");
    EXPECT_EQ(max(abs(add_scalar(w, -7.0))).item(), 0.0);
    Tensor empty = Tensor::empty({0, 3});
    EXPECT_THROW(kaiming_normal_init(empty, 0, "conv.weight", 0.0, FanMode::FanOut), Error);  // zero fan
  }
  EXPECT_FALSE(init_skipped());
  normal_init(w, 0.0, 1.0, 1, "conv.weight");
  EXPECT_GT(max(abs(add_scalar(w, -7.0))).item(), 1.0);
}

// ---------------------------------------------------------------- small layers
TEST(Linear, MatchesTheAffineMapAndGradchecks) {
  Linear lin(3, 2);
  lin.to(DType::F64);
  Tensor x = Tensor::uniform({4, 3}, -1, 1, 3, DType::F64);
  const Tensor y = lin.forward(x);
  const Tensor& w = lin.parameter("weight");
  const Tensor& b = lin.parameter("bias");
  for (int64_t n = 0; n < 4; ++n)
    for (int64_t o = 0; o < 2; ++o) {
      double acc = b.at({o});
      for (int64_t i = 0; i < 3; ++i) acc += w.at({o, i}) * x.at({n, i});
      EXPECT_NEAR(y.at({n, o}), acc, 1e-12);
    }
  const GradcheckResult r =
      gradcheck([&](const TensorList& in) { return lin.forward(in[0]); }, {x, lin.parameter("weight"), lin.parameter("bias")});
  EXPECT_TRUE(r.ok) << r.message;
  EXPECT_THROW(lin.forward(Tensor::zeros({4, 5}, DType::F64)), Error);
}

TEST(LayerNorm, NormalisesTheLastDimAndGradchecks) {
  LayerNorm ln(5);
  ln.to(DType::F64);
  const Tensor y = ln.forward(Tensor::uniform({3, 5}, -2, 3, 1, DType::F64));
  for (int64_t r = 0; r < 3; ++r) {
    double m = 0, v = 0;
    for (int64_t c = 0; c < 5; ++c) m += y.at({r, c}) / 5;
    for (int64_t c = 0; c < 5; ++c) v += (y.at({r, c}) - m) * (y.at({r, c}) - m) / 5;
    EXPECT_NEAR(m, 0.0, 1e-12);
    EXPECT_NEAR(v, 1.0, 1e-4);  // eps = 1e-5 shrinks it slightly
  }
  // The module's own parameters are gradcheck inputs: gradcheck perturbs them in place.
  ln.parameter("weight").copy_(Tensor::uniform({5}, 0.5, 1.5, 2, DType::F64));
  ln.parameter("bias").copy_(Tensor::uniform({5}, -1, 1, 3, DType::F64));
  const GradcheckResult r = gradcheck([&](const TensorList& in) { return ln.forward(in[0]); },
                                      {Tensor::uniform({3, 5}, -2, 3, 4, DType::F64), ln.parameter("weight"),
                                       ln.parameter("bias")});
  EXPECT_TRUE(r.ok) << r.message;
}

TEST(Activations, FactoryBuildsEachAndRejectsUnknownNamesListingValidOnes) {
  const Tensor x = Tensor::from_vector({-2.0, -0.5, 0.5, 2.0}, {4}, DType::F64);
  EXPECT_EQ(make_activation("relu")->forward(x).to_vector(), relu(x).to_vector());
  EXPECT_EQ(make_activation("leaky_relu:0.2")->forward(x).to_vector(), leaky_relu(x, 0.2).to_vector());
  EXPECT_EQ(make_activation("elu")->forward(x).to_vector(), elu(x).to_vector());
  EXPECT_EQ(make_activation("sigmoid")->forward(x).to_vector(), sigmoid(x).to_vector());
  EXPECT_EQ(make_activation("tanh")->forward(x).to_vector(), tanh(x).to_vector());
  EXPECT_EQ(make_activation("softplus")->forward(x).to_vector(), softplus(x).to_vector());
  EXPECT_EQ(make_activation("identity")->forward(x).to_vector(), x.to_vector());
  try {
    make_activation("gelu");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("valid: relu"), std::string::npos) << e.what();
  }
  EXPECT_THROW(make_activation("leaky_relu:abc"), Error);
}

TEST(MLP, BuildsSequentialNamesAndMapsShapes) {
  MLP mlp({.widths = {2, 16, 16, 3}, .activation = "relu", .norm = "layer", .seed = 3});
  const auto names = names_of(mlp.named_parameters());
  const std::vector<std::string> expected = {"net.0.weight", "net.0.bias", "net.1.weight", "net.1.bias",
                                             "net.3.weight", "net.3.bias", "net.4.weight", "net.4.bias",
                                             "net.6.weight", "net.6.bias"};
  EXPECT_EQ(names, expected);
  EXPECT_EQ(mlp.forward(Tensor::zeros({7, 5, 2})).shape(), (Shape{7, 5, 3}));
  EXPECT_THROW(MLP({.widths = {2}}), Error);
  EXPECT_THROW(MLP({.widths = {2, 0, 1}}), Error);
  EXPECT_THROW(MLP({.widths = {2, 1}, .norm = "weight"}), Error);
}

}  // namespace
}  // namespace sl::test
