#include "nn/modules/unet.h"

#include "autodiff/ops.h"
#include "nn/layers.h"

namespace sl::nn {

ConvBlock::ConvBlock(int spatial_dims, int64_t in, int64_t out, const std::string& norm, int64_t groups,
                     const std::string& activation)
    : Module("ConvBlock") {
  const ConvOptions conv{.padding = 1, .bias = norm == "none"};
  seq_.push_back(register_module("conv1", make_conv(spatial_dims, in, out, 3, conv)));
  seq_.push_back(register_module("norm1", make_norm(norm, out, spatial_dims, groups)));
  seq_.push_back(register_module("act1", make_activation(activation)));
  seq_.push_back(register_module("conv2", make_conv(spatial_dims, out, out, 3, conv)));
  seq_.push_back(register_module("norm2", make_norm(norm, out, spatial_dims, groups)));
  seq_.push_back(register_module("act2", make_activation(activation)));
}

Tensor ConvBlock::forward(const Tensor& x) { return forward_chain(seq_, x); }

namespace {

// Decoder level: up (Upsample + conv) then block (ConvBlock over [up, skip]).
class UpLevel : public Module {
 public:
  UpLevel(int dims, int64_t in, int64_t out, bool skip, const UNetOptions& o) : Module("UpLevel") {
    auto up = std::make_shared<Sequential>();
    up->push_back(std::make_shared<Upsample>(2, o.upsample));
    up->push_back(make_conv(dims, in, out, 3, {.padding = 1}));
    up_ = register_module("up", up);
    block_ = register_module("block", std::make_shared<ConvBlock>(dims, skip ? 2 * out : out, out, o.norm, o.groups,
                                                                   o.activation));
  }
  Tensor forward_skip(const Tensor& x, const Tensor& skip) {
    Tensor y = up_->forward(x);
    return block_->forward(skip.defined() ? concat({y, skip}, 1) : y);
  }

 private:
  std::shared_ptr<Module> up_, block_;
};

}  // namespace

UNet::UNet(int spatial_dims, UNetOptions options) : Module(spatial_dims == 2 ? "UNet2D" : "UNet3D"),
                                                    dims_(spatial_dims), opt_(std::move(options)) {
  SL_CHECK(dims_ == 2 || dims_ == 3, "UNet: spatial_dims must be 2 or 3, got ", dims_);
  SL_CHECK(opt_.depth >= 0 && opt_.depth <= 8, type_name(), ": depth must lie in [0, 8], got ", opt_.depth);
  SL_CHECK(opt_.in_channels > 0 && opt_.out_channels > 0 && opt_.base_channels > 0, type_name(),
           ": channel counts must be positive (in ", opt_.in_channels, ", out ", opt_.out_channels, ", base ",
           opt_.base_channels, ")");
  enc_ = register_module("enc", std::make_shared<ModuleList>());
  int64_t in = opt_.in_channels;
  for (int i = 0; i <= opt_.depth; ++i) {
    const int64_t c = opt_.base_channels << i;
    enc_->push_back(std::make_shared<ConvBlock>(dims_, in, c, opt_.norm, opt_.groups, opt_.activation));
    in = c;
  }
  dec_ = register_module("dec", std::make_shared<ModuleList>());
  for (int i = opt_.depth - 1; i >= 0; --i)
    dec_->push_back(std::make_shared<UpLevel>(dims_, opt_.base_channels << (i + 1), opt_.base_channels << i,
                                              opt_.skip, opt_));
  if (dims_ == 2) pool_ = register_module("pool", std::make_shared<MaxPool2d>(2));
  else pool_ = register_module("pool", std::make_shared<MaxPool3d>(2));
  head_ = register_module("head", make_conv(dims_, opt_.base_channels, opt_.out_channels, 1));
  init_parameters(opt_.seed);
}

Tensor UNet::forward(const Tensor& x) {
  SL_CHECK(x.dim() == dims_ + 2 && x.size(1) == opt_.in_channels, type_name(), ": expected [N, ", opt_.in_channels,
           dims_ == 2 ? ", H, W]" : ", D, H, W]", ", got ", x.describe());
  for (int d = 2; d < x.dim(); ++d)
    SL_CHECK(x.size(d) % (int64_t(1) << opt_.depth) == 0, type_name(), ": every spatial extent of ",
             x.describe(), " must be divisible by 2^depth = ", int64_t(1) << opt_.depth);
  std::vector<Tensor> skips;
  Tensor y = x;
  for (size_t i = 0; i < enc_->size(); ++i) {
    if (i > 0) y = pool_->forward(y);
    y = (*enc_)[i]->forward(y);
    skips.push_back(y);
  }
  for (size_t j = 0; j < dec_->size(); ++j) {
    const Tensor& skip = skips[skips.size() - 2 - j];
    y = static_cast<UpLevel&>(*(*dec_)[j]).forward_skip(y, opt_.skip ? skip : Tensor());
  }
  return head_->forward(y);
}

}  // namespace sl::nn
