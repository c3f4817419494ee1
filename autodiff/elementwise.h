// Elementwise binary ops with NumPy broadcasting, and their backward.
//
// Contract: operands broadcast NumPy-style (trailing dims aligned; size-1 or missing dims
// stretch). Both operands must have the same floating dtype; otherwise sl::Error names the op
// and both dtypes. Incompatible shapes throw naming the op and both shapes. Gradients of a
// broadcast operand are summed back to its shape.
// Edge conventions (documented, gradcheck-tested away from the kinks):
//   minimum/maximum: on ties each operand gets half the gradient (as PyTorch).
//   pow(a, b): d/db uses log(a) only where a > 0, and is 0 elsewhere.
//   atan2(y, x): the gradient at the origin is 0 (the radius is floored at the dtype's tiny).
// Comparisons return 0/1 in the operands' dtype and are not differentiable.
#pragma once
#include "autodiff/tensor.h"

namespace sl {

Shape broadcast_shapes(const char* op, const Shape& a, const Shape& b);

Tensor add(const Tensor& a, const Tensor& b);
Tensor sub(const Tensor& a, const Tensor& b);
Tensor mul(const Tensor& a, const Tensor& b);
Tensor div(const Tensor& a, const Tensor& b);
Tensor pow(const Tensor& a, const Tensor& b);
Tensor minimum(const Tensor& a, const Tensor& b);
Tensor maximum(const Tensor& a, const Tensor& b);
Tensor atan2(const Tensor& y, const Tensor& x);
// cond != 0 selects a, else b; cond is any floating tensor and is not differentiated.
Tensor where(const Tensor& cond, const Tensor& a, const Tensor& b);

Tensor add_scalar(const Tensor& a, double s);
Tensor mul_scalar(const Tensor& a, double s);
Tensor rsub_scalar(double s, const Tensor& a);  // s - a

Tensor gt(const Tensor& a, const Tensor& b);
Tensor ge(const Tensor& a, const Tensor& b);
Tensor eq(const Tensor& a, const Tensor& b);

inline Tensor operator+(const Tensor& a, const Tensor& b) { return add(a, b); }
inline Tensor operator-(const Tensor& a, const Tensor& b) { return sub(a, b); }
inline Tensor operator*(const Tensor& a, const Tensor& b) { return mul(a, b); }
inline Tensor operator/(const Tensor& a, const Tensor& b) { return div(a, b); }
inline Tensor operator+(const Tensor& a, double s) { return add_scalar(a, s); }
inline Tensor operator-(const Tensor& a, double s) { return add_scalar(a, -s); }
inline Tensor operator*(const Tensor& a, double s) { return mul_scalar(a, s); }
inline Tensor operator/(const Tensor& a, double s) { return mul_scalar(a, 1.0 / s); }
inline Tensor operator+(double s, const Tensor& a) { return add_scalar(a, s); }
inline Tensor operator-(double s, const Tensor& a) { return rsub_scalar(s, a); }
inline Tensor operator*(double s, const Tensor& a) { return mul_scalar(a, s); }
inline Tensor operator-(const Tensor& a) { return mul_scalar(a, -1.0); }

}  // namespace sl
