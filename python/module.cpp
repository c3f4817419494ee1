// The module itself: its version, thread count, error translation and the bindings of each
// concept (python/bindings.h).
#include <filesystem>

#include <omp.h>

#include "python/bindings.h"
#include "util/version.h"

namespace sl::python {

namespace {
int g_threads = 0;
}  // namespace

void set_thread_count(int threads) {
  SL_CHECK(threads >= 1 && threads <= 4096, "set_num_threads: expected a thread count in [1, 4096], got ", threads);
  g_threads = threads;
  omp_set_num_threads(threads);
}

int thread_count() { return g_threads > 0 ? g_threads : omp_get_max_threads(); }

Compute::Compute() {
  // OpenMP's thread count is per calling thread: apply it to whichever Python thread calls.
  if (g_threads > 0) omp_set_num_threads(g_threads);
}

void check_signals() {
  if (PyErr_CheckSignals() != 0) throw py::error_already_set();
}

void raise_file_error(const std::string& message, const std::vector<std::string>& paths) {
  for (const std::string& p : paths) {
    std::error_code ec;
    if (!p.empty() && p.find(':') == std::string::npos && !std::filesystem::exists(p, ec)) {
      PyErr_SetString(PyExc_FileNotFoundError, message.c_str());
      throw py::error_already_set();
    }
  }
  PyErr_SetString(PyExc_OSError, message.c_str());
  throw py::error_already_set();
}

}  // namespace sl::python

PYBIND11_MODULE(streetlight, m) {
  namespace py = pybind11;
  using namespace sl::python;
  m.doc() =
      "Streetlight: HDR street lighting from one photo, and 3D object insertion with its shading and\n"
      "cast shadows (Wang et al., ECCV 2022), from a C++ library.\n\n"
      "  est = streetlight.Estimator()                   # the released model\n"
      "  light = est.estimate(image, (fx, fy, cx, cy))   # image: H x W x 3 uint8 sRGB\n"
      "  result = streetlight.insert(image, (fx, fy, cx, cy), light, 'truck.glb', at=(2.5, 14))\n"
      "  result.composite                                # H x W x 3 float32 in [0, 1]\n\n"
      "Bad arguments raise ValueError and unreadable files OSError, with the library's message.\n"
      "Computations release the GIL and use set_num_threads() threads.";
  m.attr("__version__") = sl::version();
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const sl::Error& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });
  m.def("set_num_threads", &set_thread_count, py::arg("threads"),
        "Sets the OpenMP threads of every later computation (any calling thread). Results are\n"
        "bitwise the same for any count.");
  m.def("get_num_threads", &thread_count, "The threads a computation uses.");
  bind_tensor(m);
  bind_photo(m);
  bind_lighting(m);
  bind_insertion(m);
  bind_training(m);
  bind_evaluation(m);
}
