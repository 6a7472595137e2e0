"""The exceptions of ropes: each C++ exception of the workspace arrives as one of these, with
the C++ message unchanged (it names the file or field, the value and what was expected).

The standard C++ ones keep pybind11's mapping: std::invalid_argument is ValueError,
std::out_of_range IndexError, std::runtime_error RuntimeError.
"""


class Error(Exception):
    """Base of every ropes-specific exception."""


class FileFormatError(Error, ValueError):
    """A file that is missing, unreadable, truncated, foreign or otherwise not what the reader
    accepts (core::FileFormatError)."""


class ConfigError(FileFormatError):
    """A config that cannot be used: a field missing, of the wrong type or out of range, or a
    name that is neither a file nor an installed config (core::ConfigError)."""


class ShapeError(Error, ValueError):
    """A numpy array of the wrong dtype or shape; the message names the expected ones."""


class ModelError(Error, ValueError):
    """A URDF that cannot be read or has an unsupported joint (sim::ModelError)."""


class MeshError(Error, ValueError):
    """A mesh file of a URDF that cannot be read (sim::MeshError)."""


class RenderError(Error, RuntimeError):
    """No OpenGL context could be made (sim::RenderError)."""


def check_callback(f, what):
    """TypeError now, not minutes later at its first call, when `f` is neither None nor
    callable."""
    if f is not None and not callable(f):
        raise TypeError(f"{what} is {f!r} ({type(f).__name__}); expected a callable or None")

