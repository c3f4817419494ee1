// The Python module `streetlight` (python/README.md): pybind11 bindings of the library. Each
// binding file wraps one concept (tensor, photo, lighting, insertion, training) and
// registers it through its bind_*() below; module.cpp assembles them.
//
// Contract shared by every binding:
// - They wrap the library: the numbers come from train/inference.h, train/photo_insertion.h,
//   train/trainer.h and tools/common (the tools' own code), so a call equals the tool's run with
//   the same settings, bit for bit.
// - numpy arrays are converted while the GIL is held; the library then runs inside a Compute
//   scope: the GIL released (other Python threads keep running) and OpenMP at the thread count
//   of streetlight.set_num_threads(). After a long call, check_signals() turns a Ctrl-C that
//   arrived meanwhile into KeyboardInterrupt.
// - Errors: sl::Error (bad input) becomes ValueError carrying the library's one-line message;
//   inside file_call() it becomes OSError, FileNotFoundError when one of the named paths does
//   not exist. Other C++ exceptions become RuntimeError.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "util/error.h"

namespace sl::python {

namespace py = pybind11;

void bind_tensor(py::module_& m);
void bind_photo(py::module_& m);
void bind_lighting(py::module_& m);
void bind_insertion(py::module_& m);
void bind_training(py::module_& m);
void bind_evaluation(py::module_& m);

// The thread count of streetlight.set_num_threads() (0: OpenMP's own default).
void set_thread_count(int threads);
int thread_count();

// The scope of a library call: releases the GIL and applies the thread count to this thread.
class Compute {
 public:
  Compute();
  Compute(const Compute&) = delete;
  Compute& operator=(const Compute&) = delete;

 private:
  py::gil_scoped_release release_;
};

// Raises KeyboardInterrupt (or what a signal handler raised) when a signal arrived. GIL held.
void check_signals();

// Raises OSError with `message`, or FileNotFoundError when one of `paths` does not exist. GIL held.
[[noreturn]] void raise_file_error(const std::string& message, const std::vector<std::string>& paths);

// Runs f(); an sl::Error it throws becomes OSError (see raise_file_error). Call with the GIL held;
// f may open a Compute scope of its own.
template <class F>
auto file_call(const std::vector<std::string>& paths, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const Error& e) {
    raise_file_error(e.what(), paths);
  }
}

// An optional path argument: "" for None.
inline std::string path_or_empty(const std::optional<std::string>& p) { return p.value_or(""); }

}  // namespace sl::python
