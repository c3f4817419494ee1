#include "nn/module.h"

#include <algorithm>

#include "autodiff/tape.h"

namespace sl::nn {

namespace {

// The first few items, then how many more: a model of another architecture can mismatch in a
// hundred tensors, and the one-line error must stay readable.
constexpr size_t kListedItems = 5;

std::string join_list(const std::vector<std::string>& items) {
  std::string s;
  for (size_t i = 0; i < items.size() && i < kListedItems; ++i) s += (i ? ", " : "") + items[i];
  if (items.size() > kListedItems) s += cat(", ... and ", items.size() - kListedItems, " more");
  return s;
}

}  // namespace

std::string StateMismatch::message() const {
  std::string s;
  if (!missing.empty()) s += cat(missing.size(), " missing: ", join_list(missing), "; ");
  if (!unexpected.empty()) s += cat(unexpected.size(), " unexpected: ", join_list(unexpected), "; ");
  if (!mismatched.empty()) s += cat(mismatched.size(), " mismatched: ", join_list(mismatched), "; ");
  if (s.size() >= 2) s.resize(s.size() - 2);
  return s;
}

StateMismatch compare_state(const StateDict& expected, const StateDict& given) {
  StateMismatch m;
  for (const auto& [name, t] : expected) {
    auto it = given.find(name);
    if (it == given.end()) {
      m.missing.push_back(name);
    } else if (it->second.shape() != t.shape() || it->second.dtype() != t.dtype()) {
      m.mismatched.push_back(cat(name, ": expected ", t.describe(), ", got ", it->second.describe()));
    }
  }
  for (const auto& [name, t] : given)
    if (!expected.count(name)) m.unexpected.push_back(name);
  return m;
}

// ---------------------------------------------------------------- Module
Module::Module(std::string type_name) : type_name_(std::move(type_name)) {}

Tensor Module::forward(const Tensor& x) {
  fail(type_name_, ": this module has no single-tensor forward (input ", x.describe(), ")");
}

void Module::check_new_name(const std::string& name) const {
  SL_CHECK(!name.empty() && name.find('.') == std::string::npos, type_name_,
           ": invalid member name '", name, "' (must be non-empty and contain no '.')");
  auto taken = [&](const auto& list) {
    return std::any_of(list.begin(), list.end(), [&](const auto& e) { return e.first == name; });
  };
  SL_CHECK(!taken(params_) && !taken(buffers_) && !taken(children_), type_name_, ": member name '",
           name, "' is already registered");
}

Tensor Module::register_parameter(const std::string& name, Tensor value) {
  check_new_name(name);
  SL_CHECK(value.defined(), type_name_, ": parameter '", name, "' is undefined");
  SL_CHECK(value.dtype() != DType::I64, type_name_, ": parameter '", name, "' must be floating, got ",
           value.describe());
  SL_CHECK(value.is_leaf(), type_name_, ": parameter '", name,
           "' must be a leaf tensor (detach() it first)");
  value.set_requires_grad(!frozen_);
  params_.emplace_back(name, value);
  return value;
}

Tensor Module::register_buffer(const std::string& name, Tensor value) {
  check_new_name(name);
  SL_CHECK(value.defined(), type_name_, ": buffer '", name, "' is undefined");
  buffers_.emplace_back(name, value);
  return value;
}

void Module::add_child(const std::string& name, std::shared_ptr<Module> module) {
  check_new_name(name);
  SL_CHECK(module != nullptr, type_name_, ": child module '", name, "' is null");
  SL_CHECK(module.get() != this, type_name_, ": a module cannot be its own child ('", name, "')");
  children_.emplace_back(name, std::move(module));
}

template <class List>
static auto* find_member(List& list, const std::string& name) {
  for (auto& e : list)
    if (e.first == name) return &e.second;
  return static_cast<decltype(&list.front().second)>(nullptr);
}

Tensor& Module::parameter(const std::string& name) {
  Tensor* t = find_member(params_, name);
  SL_CHECK(t, type_name_, ": no parameter named '", name, "'");
  return *t;
}
const Tensor& Module::parameter(const std::string& name) const {
  return const_cast<Module*>(this)->parameter(name);
}
Tensor& Module::buffer(const std::string& name) {
  Tensor* t = find_member(buffers_, name);
  SL_CHECK(t, type_name_, ": no buffer named '", name, "'");
  return *t;
}
const Tensor& Module::buffer(const std::string& name) const {
  return const_cast<Module*>(this)->buffer(name);
}
bool Module::has_parameter(const std::string& name) const {
  return find_member(const_cast<NamedTensors&>(params_), name) != nullptr;
}
std::shared_ptr<Module> Module::child(const std::string& name) const {
  for (const auto& [n, m] : children_)
    if (n == name) return m;
  fail(type_name_, ": no child module named '", name, "'");
}

// ---------------------------------------------------------------- recursive views
void Module::collect(const std::string& prefix, bool params, NamedTensors& out) const {
  for (const auto& [name, t] : params ? params_ : buffers_) out.emplace_back(prefix + name, t);
  for (const auto& [name, m] : children_) m->collect(prefix + name + ".", params, out);
}

NamedTensors Module::named_parameters() const {
  NamedTensors out;
  collect("", true, out);
  return out;
}

NamedTensors Module::named_buffers() const {
  NamedTensors out;
  collect("", false, out);
  return out;
}

std::vector<Tensor> Module::parameters() const {
  std::vector<Tensor> out;
  for (auto& [name, t] : named_parameters()) out.push_back(t);
  return out;
}

void Module::collect_modules(const std::string& prefix,
                             std::vector<std::pair<std::string, Module*>>& out) {
  out.emplace_back(prefix, this);
  for (auto& [name, m] : children_) m->collect_modules(prefix.empty() ? name : prefix + "." + name, out);
}

std::vector<std::pair<std::string, Module*>> Module::named_modules() {
  std::vector<std::pair<std::string, Module*>> out;
  collect_modules("", out);
  return out;
}

StateDict Module::state_dict() const {
  StateDict out;
  for (auto& [name, t] : named_parameters()) out.emplace(name, t);
  for (auto& [name, t] : named_buffers()) out.emplace(name, t);
  return out;
}

void Module::load_state_dict(const StateDict& state) {
  StateDict own = state_dict();
  const StateMismatch m = compare_state(own, state);
  SL_CHECK(m.empty(), type_name_, ".load_state_dict: ", m.message());
  NoGradGuard no_grad;
  for (auto& [name, t] : own) t.copy_(state.at(name));
}

// ---------------------------------------------------------------- modes
void Module::train(bool on) {
  training_ = on;
  for (auto& [name, m] : children_) m->train(on);
}

void Module::zero_grad() {
  for (auto& [name, t] : params_) t.zero_grad();
  for (auto& [name, m] : children_) m->zero_grad();
}

int64_t Module::parameter_count(bool trainable_only) const {
  int64_t n = 0;
  for (auto& [name, t] : named_parameters())
    if (!trainable_only || t.requires_grad()) n += t.numel();
  return n;
}

void Module::freeze(bool frozen) {
  frozen_ = frozen;
  for (auto& [name, t] : params_) {
    t.set_requires_grad(!frozen);
    if (frozen) t.zero_grad();
  }
  for (auto& [name, m] : children_) m->freeze(frozen);
}

void Module::to(DType dtype) {
  SL_CHECK(dtype != DType::I64, type_name_, ".to: target dtype must be floating");
  NoGradGuard no_grad;
  auto convert = [&](NamedTensors& list, bool is_param) {
    for (auto& [name, t] : list) {
      if (t.dtype() == DType::I64 || t.dtype() == dtype) continue;
      Tensor c = t.to(dtype);
      if (is_param) c.set_requires_grad(!frozen_);
      t = c;
    }
  };
  convert(params_, true);
  convert(buffers_, false);
  for (auto& [name, m] : children_) m->to(dtype);
}

void Module::init_parameters(uint64_t seed) {
  NoGradGuard no_grad;
  // Children before parents, so a block (ResNet) can override its layers' default init.
  auto mods = named_modules();
  for (auto it = mods.rbegin(); it != mods.rend(); ++it)
    it->second->reset_parameters(seed, it->first.empty() ? "" : it->first + ".");
}

// ---------------------------------------------------------------- containers
ModuleList::ModuleList(std::vector<std::shared_ptr<Module>> modules) : Module("ModuleList") {
  for (auto& m : modules) push_back(std::move(m));
}

void ModuleList::push_back(std::shared_ptr<Module> module) {
  register_module(std::to_string(size()), std::move(module));
}

const std::shared_ptr<Module>& ModuleList::operator[](size_t i) const {
  SL_CHECK(i < size(), type_name(), "[", i, "]: index out of range for ", size(), " modules");
  return children()[i].second;
}

Sequential::Sequential(std::vector<std::shared_ptr<Module>> modules) : ModuleList("Sequential") {
  for (auto& m : modules) push_back(std::move(m));
}

Tensor Module::forward_absorbing(const Tensor&, const Module&) { return Tensor(); }

Tensor forward_chain(const std::vector<std::shared_ptr<Module>>& modules, const Tensor& x) {
  Tensor y = x;
  for (size_t i = 0; i < modules.size(); ++i) {
    if (i + 1 < modules.size()) {
      Tensor fused = modules[i]->forward_absorbing(y, *modules[i + 1]);
      if (fused.defined()) {
        y = std::move(fused);
        ++i;
        continue;
      }
    }
    y = modules[i]->forward(y);
  }
  return y;
}

Tensor Sequential::forward(const Tensor& x) {
  std::vector<std::shared_ptr<Module>> modules;
  modules.reserve(children().size());
  for (const auto& [name, m] : children()) modules.push_back(m);
  return forward_chain(modules, x);
}

}  // namespace sl::nn
