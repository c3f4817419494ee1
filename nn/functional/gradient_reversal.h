// Gradient reversal (Ganin & Lempitsky, "Unsupervised Domain Adaptation by Backpropagation",
// ICML 2015): the identity on the way forward, −λ times the incoming gradient on the way back.
// Put between a feature extractor and a domain classifier, one loss trains the classifier to tell
// the domains apart and the features to make them indistinguishable (train/lighting_stage.h,
// loss.domain_adversarial).
//
// Contract: gradient_reversal(x, lambda) returns a fresh tensor equal to x (any floating dtype and
// strides); backward maps dy to −lambda · dy. lambda = −1 is the identity, whose gradient
// gradchecks. Requires a finite lambda. One tape node.
#pragma once
#include "autodiff/tensor.h"

namespace sl::nn {

Tensor gradient_reversal(const Tensor& x, double lambda);

}  // namespace sl::nn
