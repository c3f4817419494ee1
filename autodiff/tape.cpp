#include "autodiff/tape.h"

#include <algorithm>

#include "autodiff/ops.h"
#include "util/check.h"
#include "util/parallel.h"

namespace sl {
namespace {

struct Tape {
  std::vector<std::shared_ptr<Node>> nodes;
  uint64_t next_seq = 0;
  size_t sweep_at = 4096;
  bool grad_enabled = true;
};

thread_local Tape g_tape;

bool node_is_dead(const Node& n) {
  for (const auto& w : n.outputs)
    if (!w.expired()) return false;
  return true;
}

// Drops nodes no one can backprop through any more. Walking in reverse lets one pass free
// whole chains: freeing a node releases its inputs, which may kill the node before it.
void sweep_dead_nodes(Tape& tape) {
  for (size_t i = tape.nodes.size(); i-- > 0;)
    if (node_is_dead(*tape.nodes[i])) tape.nodes[i].reset();
  tape.nodes.erase(std::remove(tape.nodes.begin(), tape.nodes.end(), nullptr), tape.nodes.end());
  tape.sweep_at = std::max<size_t>(4096, 2 * tape.nodes.size());
}

// True when `t` is the only handle to a dense buffer of its own: nothing else can observe an
// in-place write to it.
bool exclusively_owned(const Tensor& t) {
  return t.impl().use_count() == 1 && t.is_contiguous() && t.storage().use_count() == 1 &&
         t.storage()->bytes() == static_cast<size_t>(t.numel()) * dtype_size(t.dtype());
}

// dst += src elementwise in place (dst exclusively owned, src contiguous, same shape and dtype).
// Each element is one IEEE addition, so the bits equal those of add(dst, src) and add(src, dst).
void add_in_place(Tensor& dst, const Tensor& src) {
  SL_DISPATCH_FLOAT(dst.dtype(), "backward", [&] {
    using T = scalar_t;
    T* d = dst.data<T>();
    const T* s = src.data<T>();
    parallel_for(dst.numel(), 32768, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i) d[i] += s[i];
    });
  });
}

// slot += g without a new buffer where one of the two may be overwritten; slot = g when empty.
void add_into(Tensor& slot, Tensor g) {
  if (!slot.defined()) {
    slot = std::move(g);
  } else if (exclusively_owned(slot) && g.is_contiguous() && g.dtype() == slot.dtype()) {
    add_in_place(slot, g);
  } else if (exclusively_owned(g) && slot.is_contiguous() && g.dtype() == slot.dtype()) {
    add_in_place(g, slot);
    slot = std::move(g);
  } else {
    slot = add(slot, g);
  }
}

// Leaves collect into .grad(), which must own its memory (exclusively_owned): later in-place
// updates must not alias another tensor, and a gradient that is a view must not pin a larger
// buffer. Op outputs into their producer's pending slot, which outlives
// the output tensor itself (a node's inputs may be freed before their producer runs). A leaf
// gradient that still shares memory is listed in `borrowed` and made to own its memory once
// backward ends (by then its other holders are usually gone, and no copy is needed).
void accumulate(const std::shared_ptr<TensorImpl>& target, Tensor g, const std::string& op,
                std::vector<std::shared_ptr<TensorImpl>>* borrowed) {
  TensorImpl& impl = *target;
  SL_ASSERT(g.shape() == impl.shape, "backward of ", op, ": gradient ", g.describe(),
            " does not match its input's shape ", shape_str(impl.shape));
  if (g.dtype() != impl.dtype) g = g.to(impl.dtype);
  if (!impl.has_producer) {
    const bool first = !impl.grad.defined();
    add_into(impl.grad, std::move(g));
    if (first && !exclusively_owned(impl.grad)) {
      if (borrowed) borrowed->push_back(target);
      else impl.grad = impl.grad.clone();
    }
    return;
  }
  std::shared_ptr<Node> p = impl.producer.lock();
  if (!p) return;  // its graph was freed: nothing upstream can use it
  p->reached = true;
  add_into(p->pending[static_cast<size_t>(impl.output_index)], std::move(g));
}

}  // namespace

bool grad_enabled() { return g_tape.grad_enabled; }

bool needs_grad(const TensorList& inputs) {
  if (!g_tape.grad_enabled) return false;
  for (const Tensor& t : inputs)
    if (t.defined() && t.requires_grad()) return true;
  return false;
}

NoGradGuard::NoGradGuard() : previous_(g_tape.grad_enabled) { g_tape.grad_enabled = false; }
NoGradGuard::~NoGradGuard() { g_tape.grad_enabled = previous_; }

void record(const char* op, const TensorList& inputs, const TensorList& outputs, BackwardFn fn) {
  Tape& tape = g_tape;
  auto node = std::make_shared<Node>();
  node->op = op;
  node->seq = tape.next_seq++;
  for (const Tensor& t : inputs) node->inputs.push_back(t.defined() ? t.impl() : nullptr);
  for (const Tensor& t : outputs) {
    SL_CHECK(!t.impl()->has_producer && !t.requires_grad(), op,
             ": an op output must be a fresh tensor, not an input or another op's output");
    t.impl()->requires_grad = true;
    t.impl()->has_producer = true;
    t.impl()->producer = node;
    t.impl()->output_index = static_cast<int>(node->outputs.size());
    node->outputs.push_back(t.impl());
    node->output_shapes.push_back(t.shape());
    node->output_dtypes.push_back(t.dtype());
  }
  node->backward = std::move(fn);
  node->pending.resize(node->outputs.size());
  tape.nodes.push_back(std::move(node));
  if (tape.nodes.size() >= tape.sweep_at) sweep_dead_nodes(tape);
}

void backward(const Tensor& loss, const Tensor& grad_output, bool retain_graph) {
  SL_CHECK(loss.defined(), "backward: loss is undefined");
  SL_CHECK(loss.requires_grad(), "backward: loss ", loss.describe(),
           " does not require grad (no input of its graph requires grad, or it was computed "
           "under NoGradGuard)");
  Tensor seed = grad_output;
  if (!seed.defined()) {
    SL_CHECK(loss.numel() == 1, "backward: loss has shape ", shape_str(loss.shape()),
             "; pass grad_output for a loss with more than one element");
    seed = Tensor::ones(loss.shape(), loss.dtype());
  }
  SL_CHECK(seed.shape() == loss.shape(), "backward: grad_output ", seed.describe(),
           " does not match loss ", loss.describe());
  const std::shared_ptr<TensorImpl>& root_ptr = loss.impl();
  TensorImpl& root = *root_ptr;
  NoGradGuard no_grad;
  if (!root.has_producer) {  // a leaf: d leaf / d leaf
    accumulate(root_ptr, seed, "backward", nullptr);
    return;
  }
  std::shared_ptr<Node> start = root.producer.lock();
  SL_CHECK(start != nullptr,
           "backward: the graph behind this tensor was already freed by an earlier backward(); "
           "pass retain_graph=true to the first backward() to run it twice");

  Tape& tape = g_tape;
  auto it = std::find(tape.nodes.begin(), tape.nodes.end(), start);
  SL_CHECK(it != tape.nodes.end(), "backward: the loss was recorded on another thread's tape");
  const size_t start_index = static_cast<size_t>(it - tape.nodes.begin());

  std::vector<std::shared_ptr<TensorImpl>> borrowed;
  accumulate(root_ptr, seed, "backward", &borrowed);
  for (size_t i = start_index + 1; i-- > 0;) {
    std::shared_ptr<Node> node = tape.nodes[i];
    if (!node->reached) continue;
    node->reached = false;
    TensorList grads(node->outputs.size());
    for (size_t k = 0; k < grads.size(); ++k) {
      grads[k] = node->pending[k].defined() ? node->pending[k]
                                            : Tensor::zeros(node->output_shapes[k], node->output_dtypes[k]);
      node->pending[k] = Tensor();
    }
    TensorList in_grads = node->backward(grads);
    grads.clear();  // lets accumulation reuse a gradient buffer that no one else holds
    SL_ASSERT_EQ(in_grads.size(), node->inputs.size(), "backward of ", node->op,
                 " must return one gradient per input");
    for (size_t k = 0; k < node->inputs.size(); ++k) {
      const std::shared_ptr<TensorImpl>& in = node->inputs[k];
      if (in && in->requires_grad && in_grads[k].defined()) accumulate(in, std::move(in_grads[k]), node->op, &borrowed);
    }
    if (!retain_graph) tape.nodes[i].reset();
  }
  for (const auto& leaf : borrowed)
    if (leaf->grad.defined() && !exclusively_owned(leaf->grad)) leaf->grad = leaf->grad.clone();
  if (!retain_graph)
    tape.nodes.erase(std::remove(tape.nodes.begin(), tape.nodes.end(), nullptr), tape.nodes.end());
}

TensorList apply(const std::shared_ptr<Function>& fn, const TensorList& inputs) {
  TensorList outputs;
  {
    NoGradGuard no_grad;
    outputs = fn->forward(inputs);
  }
  if (needs_grad(inputs)) {
    const std::string name = fn->name();
    record(name.c_str(), inputs, outputs,
           [fn](const TensorList& g) { return fn->backward(g); });
  }
  return outputs;
}

size_t tape_size() { return g_tape.nodes.size(); }

}  // namespace sl
