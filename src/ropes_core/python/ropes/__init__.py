"""ROPES: robot pose estimation without pose labels, from Python.

Each package of the workspace installs its part of this package: ropes.dataset (ropes_core),
ropes.sim (ropes_sim), ropes.crl (ropes_crl) and ropes.eval (ropes_eval), each a thin layer
over its C++ extension module. After ``. install/setup.bash`` every part is on the path;
``import ropes`` loads none of them until it is used (``ropes.sim.Robot(...)``).
"""
import importlib
import pkgutil

# the parts live in one install prefix per package: let every ropes/ on sys.path count
__path__ = pkgutil.extend_path(__path__, __name__)

from .errors import (ConfigError, Error, FileFormatError, MeshError, ModelError,  # noqa: E402
                     RenderError, ShapeError)

# the exceptions; the parts are imported by name (`from ropes import sim`), never by `*`,
# which would load every extension and shadow the builtin eval
__all__ = ["ConfigError", "Error", "FileFormatError", "MeshError", "ModelError", "RenderError",
           "ShapeError"]

_PARTS = ("dataset", "sim", "crl", "eval")


def __getattr__(name):
    if name in _PARTS:
        return importlib.import_module("." + name, __name__)
    raise AttributeError(f"module 'ropes' has no attribute '{name}'")
