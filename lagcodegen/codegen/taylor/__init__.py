"""The C of the Taylor integrator: a scene's equations decomposed into elementary operations
(:mod:`.decompose`) whose Taylor recurrences are printed (:mod:`.emit`, with the first orders
written out by :mod:`.unroll`): the model's jet for the Taylor runtime's model-independent driver,
or the standalone ``<prefix>_taylor.h``/``.c`` of bundles; and the variational jet of the states
and their sensitivities (:mod:`.variational`, fused by :mod:`.schedule`, printed by
:mod:`.variational_source`).

Generation only: :mod:`lagcodegen.libraries` compiles the jets on a solver's request, and
:mod:`lagcodegen.solvers.taylor` runs them. Importing this package makes C bundles carry the
Taylor integrator (:func:`bundle_sources`, :func:`lagcodegen.codegen.bundle.register_integrator`).
"""

from ..bundle import register_integrator
from .emit import taylor_sources


def bundle_sources(scene, y0, params, t_end: float) -> dict[str, str]:
    """The Taylor integrator of a C bundle: ``<prefix>_taylor.[ch]`` and ``taylor_example.c``
    (from the bundle's initial state ``y0`` and run-time parameter values ``params``)."""
    return taylor_sources(scene, example=True, y0=y0, param_values=params, t_end=t_end)


register_integrator("taylor", bundle_sources)
