// Module: the base of every layer and model, holding named parameters, buffers and children.
//
// Contract:
// - Names are hierarchical, PyTorch style: a parameter `weight` of child `conv1` of child `0`
//   of child `layer1` is `layer1.0.conv1.weight`. Local names are non-empty and contain no '.';
//   registering a name twice in one module (as a parameter, buffer or child) throws.
// - named_parameters() / named_buffers() list members in registration order, own members
//   first, then each child's in registration order (as torch.nn.Module).
// - Parameters are leaf tensors; they require grad unless the module is frozen. freeze(true)
//   turns requires_grad off for every parameter of this module and its descendants (and drops
//   their gradients): they receive no gradient, yet ops still record when their other inputs
//   require grad, so gradients flow THROUGH a frozen module to its inputs (the paper's frozen
//   sky decoder, Sec 3.4).
// - train(bool) / eval() set the training flag recursively (dropout, batch norm read it).
// - state_dict() maps every parameter and buffer name to its tensor (shared handles, not
//   copies). load_state_dict() checks every name, shape and dtype first and throws ONE sl::Error
//   listing what is missing, unexpected or mismatched; only then does it copy values in place,
//   so tensor handles held elsewhere (optimisers) stay valid.
// - init_parameters(seed) re-initialises every parameter; each value is a pure function of the
//   seed and the parameter's full name (nn/init.h), so adding a module elsewhere in a model
//   never changes another module's initial values. Call it on the outermost model. Modules
//   are visited children first, so a block's reset_parameters may override its layers' init.
// - to(dtype) converts floating parameters and buffers (F64 for gradient checks). It replaces
//   the tensors: build optimisers afterwards.
// - A Module is not copyable; share it through std::shared_ptr.
#pragma once
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "autodiff/tensor.h"

namespace sl::nn {

using NamedTensors = std::vector<std::pair<std::string, Tensor>>;
using StateDict = std::map<std::string, Tensor>;

// What differs between an expected and a given set of named tensors.
struct StateMismatch {
  std::vector<std::string> missing;     // expected, not given
  std::vector<std::string> unexpected;  // given, not expected
  std::vector<std::string> mismatched;  // "name: expected f32[3, 4], got f64[3]"
  bool empty() const { return missing.empty() && unexpected.empty() && mismatched.empty(); }
  std::string message() const;  // one line: each group's count and its first 5 entries
};

// Compares names, shapes and dtypes (values are not looked at).
StateMismatch compare_state(const StateDict& expected, const StateDict& given);

class Module {
 public:
  explicit Module(std::string type_name);
  virtual ~Module() = default;
  Module(const Module&) = delete;
  Module& operator=(const Module&) = delete;

  const std::string& type_name() const { return type_name_; }

  // The single-tensor forward used by Sequential and most layers. Modules with other
  // signatures (ResNet, UNet) add their own methods; the default throws naming the type.
  virtual Tensor forward(const Tensor& x);
  Tensor operator()(const Tensor& x) { return forward(x); }
  // next.forward(forward(x)) as one op when this module can absorb `next` (a normalisation
  // absorbs a following ReLU / LeakyReLU, bitwise the same result); an undefined Tensor when
  // it cannot (the default). Chains (Sequential, blocks) use it through forward_chain below.
  // A subclass that changes forward must change forward_absorbing the same way.
  virtual Tensor forward_absorbing(const Tensor& x, const Module& next);

  // ---- registration
  // Return the registered handle (the value, now a named leaf).
  Tensor register_parameter(const std::string& name, Tensor value);
  Tensor register_buffer(const std::string& name, Tensor value);
  template <class M>
  std::shared_ptr<M> register_module(const std::string& name, std::shared_ptr<M> module) {
    add_child(name, module);
    return module;
  }

  // ---- own members by local name (throw naming the module type and the name when absent).
  // References stay valid until the next registration in this module.
  Tensor& parameter(const std::string& name);
  const Tensor& parameter(const std::string& name) const;
  Tensor& buffer(const std::string& name);
  const Tensor& buffer(const std::string& name) const;
  bool has_parameter(const std::string& name) const;
  std::shared_ptr<Module> child(const std::string& name) const;
  const std::vector<std::pair<std::string, std::shared_ptr<Module>>>& children() const { return children_; }

  // ---- recursive views
  NamedTensors named_parameters() const;
  NamedTensors named_buffers() const;
  std::vector<Tensor> parameters() const;
  // Every module with its full name; this module is "".
  std::vector<std::pair<std::string, Module*>> named_modules();
  StateDict state_dict() const;
  void load_state_dict(const StateDict& state);

  void train(bool on = true);
  void eval() { train(false); }
  bool is_training() const { return training_; }
  void zero_grad();
  int64_t parameter_count(bool trainable_only = false) const;
  void freeze(bool frozen = true);
  bool is_frozen() const { return frozen_; }
  void to(DType dtype);
  void init_parameters(uint64_t seed);

 protected:
  // Initialises this module's own parameters (a block may also re-initialise its descendants,
  // which were visited before it); `prefix` is this module's full name plus '.' (or "" at the
  // top) so that init functions key the values on full parameter names.
  virtual void reset_parameters(uint64_t seed, const std::string& prefix) {}

 private:
  void add_child(const std::string& name, std::shared_ptr<Module> module);
  void check_new_name(const std::string& name) const;
  void collect(const std::string& prefix, bool params, NamedTensors& out) const;
  void collect_modules(const std::string& prefix, std::vector<std::pair<std::string, Module*>>& out);

  std::string type_name_;
  NamedTensors params_;
  NamedTensors buffers_;
  std::vector<std::pair<std::string, std::shared_ptr<Module>>> children_;
  bool training_ = true;
  bool frozen_ = false;
};

// Children named 0, 1, 2, ... in insertion order.
class ModuleList : public Module {
 public:
  ModuleList() : Module("ModuleList") {}
  explicit ModuleList(std::vector<std::shared_ptr<Module>> modules);
  void push_back(std::shared_ptr<Module> module);
  size_t size() const { return children().size(); }
  const std::shared_ptr<Module>& operator[](size_t i) const;

 protected:
  explicit ModuleList(std::string type_name) : Module(std::move(type_name)) {}
};

// Applies modules in order, letting each absorb its successor (Module::forward_absorbing).
Tensor forward_chain(const std::vector<std::shared_ptr<Module>>& modules, const Tensor& x);

// A ModuleList whose forward applies its children in order (forward_chain).
class Sequential : public ModuleList {
 public:
  Sequential() : ModuleList("Sequential") {}
  explicit Sequential(std::vector<std::shared_ptr<Module>> modules);
  Tensor forward(const Tensor& x) override;
};

}  // namespace sl::nn
