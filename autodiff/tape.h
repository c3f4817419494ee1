// The tape: reverse-mode automatic differentiation.
//
// Contract:
// - Each differentiable op that sees an input requiring grad (and grad mode on) appends ONE
//   node to the calling thread's tape: its inputs, its outputs and a backward function.
//   Nodes are appended in execution order; backward(loss) walks them in reverse.
// - backward(loss) seeds d loss / d loss = 1 (loss must have one element, or pass grad_output),
//   runs every node the loss depends on, and ACCUMULATES into .grad() of leaves that require
//   grad. Intermediate gradients are freed as soon as their node has run.
// - Unless retain_graph is true, the nodes it ran are freed with everything they saved, so
//   memory returns to its level from before the forward pass. Calling backward again through
//   a freed node throws sl::Error. Nodes of other, independent graphs stay on the tape
//   (a GAN can backprop its discriminator loss and later its generator loss).
// - Nodes whose outputs are all gone (forward results dropped without backward) are swept
//   from the tape automatically; NoGradGuard avoids recording them in the first place.
// - Backward functions run with grad mode off: no double backward.
// - The tape is per thread; so is grad mode.
//
// Custom ops (the renderer, losses and samplers plug in here) subclass Function:
//
//   // y = x² with a hand-written backward, recorded as one node.
//   struct Square : sl::Function {
//     sl::Tensor x;                                     // what backward needs
//     std::string name() const override { return "square"; }
//     sl::TensorList forward(const sl::TensorList& in) override {
//       x = in[0].detach();                             // keep data, not the graph
//       return {sl::mul(x, x)};                         // runs with grad mode off
//     }
//     sl::TensorList backward(const sl::TensorList& grad_out) override {
//       return {sl::mul(grad_out[0], sl::mul_scalar(x, 2.0))};  // one grad per input
//     }
//   };
//   sl::Tensor y = sl::apply(std::make_shared<Square>(), {x})[0];
//
// forward must return fresh tensors (not views of inputs). backward receives one gradient
// per output (zeros where an output got none) and returns one per input, each with the
// input's shape, or an undefined Tensor for an input that needs no gradient. The Function
// object is released when the node is freed, and with it everything forward kept.
#pragma once
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "autodiff/tensor.h"

namespace sl {

using TensorList = std::vector<Tensor>;
using BackwardFn = std::function<TensorList(const TensorList& grad_outputs)>;

struct Node {
  std::string op;
  uint64_t seq = 0;
  std::vector<std::shared_ptr<TensorImpl>> inputs;
  std::vector<std::weak_ptr<TensorImpl>> outputs;
  std::vector<Shape> output_shapes;
  std::vector<DType> output_dtypes;
  BackwardFn backward;
  std::vector<Tensor> pending;  // gradients w.r.t. the outputs, gathered during backward
  bool reached = false;
};

// True when grad mode is on and any input requires grad.
bool needs_grad(const TensorList& inputs);
bool grad_enabled();

// Appends a node; marks outputs as requiring grad and produced by it.
void record(const char* op, const TensorList& inputs, const TensorList& outputs, BackwardFn backward);

void backward(const Tensor& loss, const Tensor& grad_output = Tensor(), bool retain_graph = false);

// Disables recording in its scope (nestable).
class NoGradGuard {
 public:
  NoGradGuard();
  ~NoGradGuard();
  NoGradGuard(const NoGradGuard&) = delete;
  NoGradGuard& operator=(const NoGradGuard&) = delete;

 private:
  bool previous_;
};

class Function {
 public:
  virtual ~Function() = default;
  virtual std::string name() const = 0;
  virtual TensorList forward(const TensorList& inputs) = 0;
  virtual TensorList backward(const TensorList& grad_outputs) = 0;
};

TensorList apply(const std::shared_ptr<Function>& fn, const TensorList& inputs);

// Nodes currently on this thread's tape (for tests and diagnostics).
size_t tape_size();

}  // namespace sl
