// Bilinear 2D and trilinear 3D grid sampling (torch.nn.functional.grid_sample semantics).
//
// Contract:
//   grid_sample_2d(input [N,C,H,W], grid [N,Ho,Wo,2]) -> [N,C,Ho,Wo]; grid[...,0] is x (width),
//   grid[...,1] is y (height), both in [-1, 1].
//   grid_sample_3d(input [N,C,D,H,W], grid [N,Do,Ho,Wo,3]) -> [N,C,Do,Ho,Wo]; (x, y, z) map to
//   (W, H, D).
//   align_corners as in PyTorch; padding Zeros (outside samples read 0) or Border (clamped).
// Differentiable in both input and grid. Backward into the input is accumulated per (n, c)
// plane in a fixed order, so it is deterministic for any thread count. NaN grid coordinates
// read as outside (0 with Zeros) and receive zero gradient.
#pragma once
#include "autodiff/tensor.h"

namespace sl {

enum class GridPadding { Zeros, Border };

Tensor grid_sample_2d(const Tensor& input, const Tensor& grid, bool align_corners = false,
                      GridPadding padding = GridPadding::Zeros);
Tensor grid_sample_3d(const Tensor& input, const Tensor& grid, bool align_corners = false,
                      GridPadding padding = GridPadding::Zeros);

}  // namespace sl
