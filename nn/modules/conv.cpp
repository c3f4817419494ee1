#include "nn/modules/conv.h"

#include "nn/functional/conv.h"
#include "autodiff/tape.h"
#include "nn/init.h"

namespace sl::nn {

ConvNd::ConvNd(const char* type_name, int spatial_dims, int64_t in, int64_t out, int64_t kernel,
               ConvOptions options)
    : Module(type_name), dims_(spatial_dims), in_(in), out_(out), kernel_(kernel), opt_(options) {
  SL_CHECK(in > 0 && out > 0 && kernel > 0, type_name, ": channels and kernel must be positive, got in=", in,
           " out=", out, " kernel=", kernel);
  SL_CHECK(options.stride > 0 && options.dilation > 0 && options.padding >= 0, type_name, ": stride ",
           options.stride, " and dilation ", options.dilation, " must be >= 1 and padding ", options.padding,
           " >= 0");
  Shape w{out, in};
  for (int d = 0; d < dims_; ++d) w.push_back(kernel);
  register_parameter("weight", Tensor::empty(w));
  if (options.bias) register_parameter("bias", Tensor::empty({out}));
  reset_parameters(0, "");
}

void ConvNd::reset_parameters(uint64_t seed, const std::string& prefix) {
  Tensor none;
  default_layer_init(parameter("weight"), opt_.bias ? parameter("bias") : none, seed, prefix);
}

Tensor ConvNd::forward(const Tensor& x) {
  SL_CHECK(x.dim() == dims_ + 2 && x.size(1) == in_, type_name(), "(", in_, " -> ", out_, ", k=", kernel_,
           "): expected input [N, ", in_, dims_ == 2 ? ", H, W]" : ", D, H, W]", ", got ", x.describe());
  const Tensor& w = parameter("weight");
  const Tensor b = opt_.bias ? parameter("bias") : Tensor();
  const int64_t s = opt_.stride, p = opt_.padding, d = opt_.dilation;
  if (dims_ == 2) return conv2d(x, w, b, {s, s}, {p, p}, {d, d});
  return conv3d(x, w, b, {s, s, s}, {p, p, p}, {d, d, d});
}

void ConvNd::scale_outputs(const std::vector<double>& scale, const std::vector<double>& shift) {
  SL_CHECK(static_cast<int64_t>(scale.size()) == out_ && static_cast<int64_t>(shift.size()) == out_, type_name(),
           "::scale_outputs: expected ", out_, " scales and shifts, got ", scale.size(), " and ", shift.size());
  const NoGradGuard no_grad;
  if (!opt_.bias) {
    register_parameter("bias", Tensor::zeros({out_}, parameter("weight").dtype()))
        .set_requires_grad(parameter("weight").requires_grad());
    opt_.bias = true;
  }
  // References taken after the registration (it may move the parameter list).
  Tensor& w = parameter("weight");
  Tensor& b = parameter("bias");
  std::vector<double> wv = w.to_vector(), bv = b.to_vector();
  const int64_t per_out = w.numel() / out_;
  for (int64_t o = 0; o < out_; ++o) {
    for (int64_t i = 0; i < per_out; ++i) wv[o * per_out + i] *= scale[o];
    bv[o] = bv[o] * scale[o] + shift[o];
  }
  w.copy_(Tensor::from_vector(wv, w.shape(), w.dtype()));  // in place: the parameter keeps its identity
  b.copy_(Tensor::from_vector(bv, b.shape(), b.dtype()));
}

std::shared_ptr<ConvNd> make_conv(int spatial_dims, int64_t in, int64_t out, int64_t kernel, ConvOptions options) {
  SL_CHECK(spatial_dims == 2 || spatial_dims == 3, "make_conv: spatial_dims must be 2 or 3, got ", spatial_dims);
  if (spatial_dims == 2) return std::make_shared<Conv2d>(in, out, kernel, options);
  return std::make_shared<Conv3d>(in, out, kernel, options);
}

}  // namespace sl::nn
