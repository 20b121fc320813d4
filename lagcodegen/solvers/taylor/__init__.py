"""Taylor-series integration emitted as plain C (libm only, no SUNDIALS).

:mod:`.decompose` turns a scene's equations into elementary operations, :mod:`.emit` renders
the C jet, stepper and driver (the model's jet for the Taylor runtime's model-independent driver,
or the standalone ``<prefix>_taylor.h``/``.c`` of bundles), :mod:`.runner` compiles them and
calls the driver through cffi. The family: its options object :class:`~.options.Taylor`, its runner
(:mod:`.run`) and its ensemble runner (:mod:`.ensemble`).
"""

from ...codegen.bundle import register_integrator
from .decompose import Decomposition, Op, decompose  # noqa: F401
from .emit import P_MAX, taylor_sources  # noqa: F401
from .options import Taylor  # noqa: F401
from .runner import TaylorModule, build_taylor, jet_code, taylor_code, taylor_runtime  # noqa: F401


def bundle_sources(scene, y0, params, t_end: float) -> dict[str, str]:
    """The Taylor integrator of a C bundle: ``<prefix>_taylor.[ch]`` and ``taylor_example.c``
    (from the bundle's initial state ``y0`` and run-time parameter values ``params``)."""
    return taylor_sources(scene, example=True, y0=y0, param_values=params, t_end=t_end)


register_integrator("taylor", bundle_sources)

__all__ = ["Decomposition", "Op", "P_MAX", "Taylor", "TaylorModule", "build_taylor", "decompose", "jet_code", "taylor_code",
           "taylor_runtime",
           "taylor_sources"]
