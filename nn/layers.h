// Every layer module, for code that builds models (see the per-family headers for contracts).
#pragma once
#include "nn/activations.h"
#include "nn/layer_norm.h"
#include "nn/layers_conv.h"
#include "nn/layers_dropout.h"
#include "nn/layers_linear.h"
#include "nn/layers_norm.h"
#include "nn/layers_resample.h"
#include "nn/module.h"
