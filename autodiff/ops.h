// Every differentiable op of the autodiff engine. Include this for the whole set.
#pragma once
#include "autodiff/elementwise.h"
#include "autodiff/grid_sample.h"
#include "autodiff/indexing.h"
#include "autodiff/matmul.h"
#include "autodiff/reduce.h"
#include "autodiff/shape_ops.h"
#include "autodiff/tape.h"
#include "autodiff/tensor.h"
#include "autodiff/unary.h"
