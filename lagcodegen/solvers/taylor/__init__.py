"""Taylor-series integration emitted as plain C (libm only, no SUNDIALS).

:mod:`.decompose` turns a scene's equations into elementary operations, :mod:`.emit` renders
the C jet, stepper and driver (``<prefix>_taylor.h``/``.c``), :mod:`.runner` compiles them and
calls the driver through cffi.
"""

from .decompose import Decomposition, Op, decompose  # noqa: F401
from .emit import P_MAX, taylor_sources  # noqa: F401
from .runner import TaylorModule, build_taylor, taylor_code  # noqa: F401

__all__ = ["Decomposition", "Op", "P_MAX", "TaylorModule", "build_taylor", "decompose", "taylor_code",
           "taylor_sources"]
