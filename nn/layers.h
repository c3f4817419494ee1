// Every layer module, for code that builds models (see the per-family headers for contracts).
#pragma once
#include "nn/module.h"
#include "nn/modules/activations.h"
#include "nn/modules/conv.h"
#include "nn/modules/depthwise_conv.h"
#include "nn/modules/dropout.h"
#include "nn/modules/flatten.h"
#include "nn/modules/layer_norm.h"
#include "nn/modules/linear.h"
#include "nn/modules/norm.h"
#include "nn/modules/pool.h"
#include "nn/modules/upsample.h"
