#pragma once
/// @file python.hpp
/// What the workspace's Python extension modules share (RopesPython.cmake builds them; this
/// header needs pybind11 and is included by them alone): exception translation into
/// ropes.errors, numpy arrays checked and converted, JSON as Python objects, and Python
/// callbacks called from C++ threads that can stop the computation.
///
/// Exceptions: the classes live in the pure-Python module ropes.errors, so that every
/// extension module raises the same ones; each module registers, for itself, which C++
/// type becomes which class (translate_exception). The message is the C++ one, unchanged.
/// pybind11's own mapping stays for the standard types: std::invalid_argument is ValueError,
/// std::out_of_range IndexError, std::runtime_error RuntimeError.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <exception>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "ropes_core/dtype.hpp"
#include "ropes_core/file_format_error.hpp"
#include "ropes_core/npy.hpp"

namespace ropes::python {

namespace py = pybind11;

/// An array of the wrong dtype or shape; Python sees ropes.errors.ShapeError (a ValueError).
class ShapeError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// Thrown through a C++ computation when a Python callback returned False or raised (see
/// Callback); the binding catches it once the computation has unwound.
class CallbackStop : public std::exception {
 public:
  const char* what() const noexcept override { return "stopped by a Python callback"; }
};

/// The class ropes.errors.<name>.
inline py::object error_class(const char* name) {
  return py::module_::import("ropes.errors").attr(name);
}

/// Registers, for the calling module, C++ exception E as ropes.errors.<python_name> with the
/// same message. A module's translators are tried last-registered first: register a base
/// class before the classes derived from it.
template <class E>
void translate_exception(const char* python_name) {
  // a translator is a plain function: the class name waits in a static of its own per E
  static const char* name = nullptr;
  name = python_name;
  py::register_local_exception_translator([](std::exception_ptr p) {
    try {
      if (p)
        std::rethrow_exception(p);
    } catch (const E& e) {
      PyErr_SetString(error_class(name).ptr(), e.what());
    }
  });
}

/// The translations every module needs: FileFormatError, ConfigError and ShapeError.
inline void translate_core_exceptions() {
  translate_exception<core::FileFormatError>("FileFormatError");
  translate_exception<core::ConfigError>("ConfigError");
  translate_exception<ShapeError>("ShapeError");
}

/// numpy's name of `dtype` ("uint8", "int32", "int64", "float32", "float64").
inline const char* numpy_dtype_name(core::DType dtype) {
  switch (dtype) {
    case core::DType::kU8:
      return "uint8";
    case core::DType::kI32:
      return "int32";
    case core::DType::kI64:
      return "int64";
    case core::DType::kF32:
      return "float32";
    case core::DType::kF64:
      return "float64";
  }
  throw std::logic_error("numpy_dtype_name: unknown dtype");
}

/// "[n, 1, 64, 64]": a shape, -1 written as the name in `names` at its position (or "n").
inline std::string shape_text(const std::vector<std::int64_t>& shape,
                              const std::vector<std::string>& names = {}) {
  std::string s = "[";
  for (std::size_t i = 0; i < shape.size(); ++i) {
    if (i)
      s += ", ";
    if (shape[i] >= 0)
      s += std::to_string(shape[i]);
    else
      s += i < names.size() ? names[i] : "n";
  }
  return s + "]";
}

/// What `obj` is, for a message: "a float64 array of shape [3, 64, 64]" or "a list".
inline std::string describe_array(const py::handle& obj) {
  if (!py::isinstance<py::array>(obj))
    return "a " + std::string(py::str(py::type::handle_of(obj).attr("__name__")));
  const py::array a = py::reinterpret_borrow<py::array>(obj);
  std::vector<std::int64_t> shape(a.shape(), a.shape() + a.ndim());
  return "a " + std::string(py::str(a.dtype().attr("name"))) + " array of shape " +
         shape_text(shape);
}

/// `obj` as a C-contiguous numpy array of T, checked to have the shape `shape` (-1: any
/// size, named by `names` in the message); copied only when it is not C-contiguous. Throws
/// ShapeError "<what>: expected a uint8 array of shape [n, 1, 64, 64], got a float64 array of
/// shape [3, 64, 64]" for anything else (another dtype is never converted).
template <class T>
py::array_t<T, py::array::c_style> require_array(const py::handle& obj, const std::string& what,
                                                 const std::vector<std::int64_t>& shape,
                                                 const std::vector<std::string>& names = {}) {
  bool ok = py::array_t<T>::check_(obj);
  if (ok) {
    const py::array a = py::reinterpret_borrow<py::array>(obj);
    ok = a.ndim() == static_cast<py::ssize_t>(shape.size());
    for (std::size_t i = 0; ok && i < shape.size(); ++i)
      ok = shape[i] < 0 || a.shape(static_cast<py::ssize_t>(i)) == shape[i];
  }
  if (!ok) {
    throw ShapeError(what + ": expected a " +
                     std::string(py::str(py::dtype::of<T>().attr("name"))) + " array of shape " +
                     shape_text(shape, names) + ", got " + describe_array(obj));
  }
  return py::array_t<T, py::array::c_style>::ensure(obj);
}

/// `a` as a numpy array that owns its bytes (moved, not copied): a zero-copy hand-over.
inline py::array to_numpy(core::NpyArray&& a) {
  auto* owner = new core::NpyArray(std::move(a));
  py::capsule free_owner(owner, [](void* p) { delete static_cast<core::NpyArray*>(p); });
  const std::vector<py::ssize_t> shape(owner->shape.begin(), owner->shape.end());
  return py::array(py::dtype(numpy_dtype_name(owner->dtype)), shape, owner->data.data(),
                   free_owner);
}

/// A std::vector<T> as a 1-d or [rows, cols] numpy array that owns it (moved).
template <class T>
py::array_t<T> to_numpy(std::vector<T>&& values, std::vector<py::ssize_t> shape) {
  auto* owner = new std::vector<T>(std::move(values));
  py::capsule free_owner(owner, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>(shape, owner->data(), free_owner);
}

/// os.fspath(obj) as a string: a str, or a pathlib.Path (TypeError for anything else).
inline std::string fspath(const py::handle& obj) {
  return py::str(py::module_::import("os").attr("fspath")(obj));
}

/// JSON as Python objects (dict, list, str, float, int, bool, None), through Python's json
/// module: numbers round-trip exactly both ways.
inline py::object to_python(const nlohmann::json& j) {
  return py::module_::import("json").attr("loads")(j.dump());
}
inline nlohmann::json from_python(const py::handle& obj) {
  const std::string text = py::str(py::module_::import("json").attr("dumps")(obj));
  return nlohmann::json::parse(text);
}

/// A Python callable (or None) that C++ code calls, from any thread, with the GIL taken, one
/// call at a time, with the arguments a `make_args` lambda builds as a py::tuple (it runs with
/// the GIL, so it may make Python objects). A call that returns False, raises, or finds a
/// pending KeyboardInterrupt (checked at every call, also without a callable, but only on the
/// main thread: Python sees signals there alone, so a call from a worker thread finds none)
/// asks the computation to stop: operator() returns false (for C++ code that can stop by itself),
/// and stop_unless_going() throws CallbackStop (for code that stops by unwinding). The binding,
/// back with the GIL, calls finish() to re-raise what the callable raised. The C++ code must
/// have released the GIL (py::gil_scoped_release).
class Callback {
 public:
  explicit Callback(py::object f) : f_(std::move(f)) {}
  Callback(const Callback&) = delete;
  Callback& operator=(const Callback&) = delete;
  ~Callback() {
    // the stored error holds Python objects: release it with the GIL
    if (error_) {
      py::gil_scoped_acquire gil;
      error_.reset();
    }
  }

  /// Calls the callable with the arguments make_args() returns; false: stop.
  template <class MakeArgs>
  bool operator()(MakeArgs&& make_args) {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (stopped_)
      return false;
    py::gil_scoped_acquire gil;
    try {
      if (PyErr_CheckSignals() != 0)
        throw py::error_already_set();
      if (!f_.is_none()) {
        const py::object r = f_(*make_args());
        if (r.ptr() == Py_False)
          stopped_ = true;
      }
    } catch (py::error_already_set& e) {
      error_.emplace(std::move(e));
      stopped_ = true;
    }
    return !stopped_;
  }

  /// The same, throwing CallbackStop to stop.
  template <class MakeArgs>
  void stop_unless_going(MakeArgs&& make_args) {
    if (!(*this)(std::forward<MakeArgs>(make_args)))
      throw CallbackStop();
  }

  /// Without calling the callable: throws CallbackStop when it asked to stop before or a
  /// KeyboardInterrupt is pending (seen on the main thread only: Python runs signal handlers
  /// there), for code that reports more often than the callable wants to hear.
  void poll() {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (!stopped_) {
      py::gil_scoped_acquire gil;
      if (PyErr_CheckSignals() != 0) {
        error_.emplace();  // fetches the KeyboardInterrupt
        stopped_ = true;
      }
    }
    if (stopped_)
      throw CallbackStop();
  }

  /// With the GIL, after the computation: re-raises what the callable raised; true when
  /// the callable stopped the computation by returning False.
  bool finish() {
    if (error_) {
      py::error_already_set e = std::move(*error_);
      error_.reset();
      throw e;
    }
    return stopped_;
  }

 private:
  py::object f_;
  std::mutex mutex_;
  bool stopped_ = false;
  std::optional<py::error_already_set> error_;
};

}  // namespace ropes::python
