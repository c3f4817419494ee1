// streetlight.Tensor: the autodiff engine's Tensor (autodiff/tensor.h) with numpy through the
// buffer protocol, and a few ops with their backward (autodiff/ops.h), enough to check a gradient
// by hand from Python.
//
// numpy(t) / numpy.asarray(t) share the tensor's storage (no copy, any strides); Tensor(array)
// copies, because the library's storage is its own 64-byte aligned buffer.
#include <cstring>

#include <pybind11/stl.h>

#include "autodiff/ops.h"
#include "python/bindings.h"
#include "python/numpy_arrays.h"

namespace sl::python {

namespace {

std::string format_of(DType d) {
  switch (d) {
    case DType::F32: return py::format_descriptor<float>::format();
    case DType::F64: return py::format_descriptor<double>::format();
    case DType::I64: return py::format_descriptor<int64_t>::format();
  }
  return "";
}

py::buffer_info buffer_of(const Tensor& t) {
  SL_CHECK(t.defined(), "Tensor: undefined");
  const ssize_t item = static_cast<ssize_t>(dtype_size(t.dtype()));
  std::vector<ssize_t> shape(t.shape().begin(), t.shape().end()), strides;
  for (int64_t s : t.strides()) strides.push_back(s * item);
  return py::buffer_info(t.raw_data(), item, format_of(t.dtype()), t.dim(), shape, strides);
}

template <class T>
Tensor copy_of(const py::array& a, DType dtype) {
  const auto c = py::array_t<T, py::array::c_style>::ensure(a);
  Shape shape(c.shape(), c.shape() + c.ndim());
  Tensor t = Tensor::empty(shape, dtype);
  if (t.numel() > 0) std::memcpy(t.raw_data(), c.data(), sizeof(T) * t.numel());
  return t;
}

Tensor tensor_from_array(const py::array& a, bool requires_grad) {
  Tensor t;
  if (a.dtype().is(py::dtype::of<float>())) {
    t = copy_of<float>(a, DType::F32);
  } else if (a.dtype().is(py::dtype::of<double>())) {
    t = copy_of<double>(a, DType::F64);
  } else if (a.dtype().is(py::dtype::of<int64_t>())) {
    t = copy_of<int64_t>(a, DType::I64);
  } else {
    fail("Tensor: expected dtype float32, float64 or int64, got ", describe_array(a));
  }
  if (requires_grad) t.set_requires_grad(true);
  return t;
}

py::array numpy_view(py::object self) {
  const Tensor& t = self.cast<const Tensor&>();
  const py::buffer_info b = buffer_of(t);
  return py::array(py::dtype(b.format), b.shape, b.strides, b.ptr, self);
}

std::vector<int64_t> axes_of(const std::optional<std::vector<int64_t>>& axes) { return axes.value_or(std::vector<int64_t>{}); }

}  // namespace

void bind_tensor(py::module_& m) {
  py::class_<Tensor>(m, "Tensor", py::buffer_protocol(),
                     "A dense row-major array of the autodiff engine (float32, float64 or int64) with its\n"
                     "gradient. numpy.asarray(t) and t.numpy() share its memory; Tensor(array) copies.\n\n"
                     "  x = streetlight.Tensor(np.array([1.0, 2.0]), requires_grad=True)\n"
                     "  y = (x * x).sum(); y.backward(); x.grad.numpy()   # [2, 4]")
      .def(py::init(&tensor_from_array), py::arg("array"), py::kw_only(), py::arg("requires_grad") = false,
           "A tensor holding a copy of `array` (float32, float64 or int64).")
      .def_buffer(&buffer_of)
      .def("numpy", &numpy_view, "A numpy array sharing this tensor's memory (no copy).")
      .def_property_readonly("shape", [](const Tensor& t) { return py::tuple(py::cast(t.shape())); })
      .def_property_readonly("dtype", [](const Tensor& t) { return std::string(dtype_name(t.dtype())); })
      .def_property("requires_grad", &Tensor::requires_grad,
                    [](Tensor& t, bool on) { t.set_requires_grad(on); }, "Leaves only.")
      .def_property_readonly("grad", [](const Tensor& t) -> std::optional<Tensor> {
            if (!t.grad().defined()) return std::nullopt;
            return t.grad();
          }, "The accumulated gradient, or None before a backward reaches this leaf.")
      .def("zero_grad", &Tensor::zero_grad)
      .def("detach", &Tensor::detach)
      .def("item", &Tensor::item)
      .def("backward", [](const Tensor& t, std::optional<Tensor> grad) {
            Compute c;
            backward(t, grad.value_or(Tensor()));
          }, py::arg("grad") = py::none(),
          "Back-propagates from this tensor (one element, or pass grad of its shape) into every leaf\n"
          "that requires a gradient.")
      .def("__repr__", [](const Tensor& t) { return "streetlight.Tensor(" + t.describe() + ")"; })
      .def("__add__", [](const Tensor& a, const Tensor& b) { return a + b; })
      .def("__add__", [](const Tensor& a, double s) { return a + s; })
      .def("__radd__", [](const Tensor& a, double s) { return a + s; })
      .def("__sub__", [](const Tensor& a, const Tensor& b) { return a - b; })
      .def("__sub__", [](const Tensor& a, double s) { return a - s; })
      .def("__rsub__", [](const Tensor& a, double s) { return s - a; })
      .def("__mul__", [](const Tensor& a, const Tensor& b) { return a * b; })
      .def("__mul__", [](const Tensor& a, double s) { return a * s; })
      .def("__rmul__", [](const Tensor& a, double s) { return a * s; })
      .def("__truediv__", [](const Tensor& a, const Tensor& b) { return a / b; })
      .def("__truediv__", [](const Tensor& a, double s) { return a / s; })
      .def("__neg__", [](const Tensor& a) { return neg(a); })
      .def("__pow__", [](const Tensor& a, double p) { return pow_scalar(a, p); })
      .def("__matmul__", [](const Tensor& a, const Tensor& b) { return matmul(a, b); })
      .def("exp", [](const Tensor& a) { return exp(a); })
      .def("log", [](const Tensor& a) { return log(a); })
      .def("sqrt", [](const Tensor& a) { return sqrt(a); })
      .def("square", [](const Tensor& a) { return square(a); })
      .def("abs", [](const Tensor& a) { return abs(a); })
      .def("sin", [](const Tensor& a) { return sin(a); })
      .def("cos", [](const Tensor& a) { return cos(a); })
      .def("tanh", [](const Tensor& a) { return tanh(a); })
      .def("sigmoid", [](const Tensor& a) { return sigmoid(a); })
      .def("relu", [](const Tensor& a) { return relu(a); })
      .def("sum", [](const Tensor& a, std::optional<std::vector<int64_t>> axes, bool keepdim) {
            return sum(a, axes_of(axes), keepdim);
          }, py::arg("axes") = py::none(), py::arg("keepdim") = false, "Sum over `axes` (all when None).")
      .def("mean", [](const Tensor& a, std::optional<std::vector<int64_t>> axes, bool keepdim) {
            return mean(a, axes_of(axes), keepdim);
          }, py::arg("axes") = py::none(), py::arg("keepdim") = false, "Mean over `axes` (all when None).")
      .def("reshape", [](const Tensor& a, std::vector<int64_t> shape) { return reshape(a, shape); }, py::arg("shape"))
      .def("transpose", [](const Tensor& a, int64_t d0, int64_t d1) { return transpose(a, d0, d1); }, py::arg("dim0"),
           py::arg("dim1"));
}

}  // namespace sl::python
