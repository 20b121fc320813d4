"""lagcodegen: Lagrangian mechanics -> standalone C code -> SUNDIALS integration.

Pipeline, one module per stage:
    model (Model) -> derivation (derive) -> scene (Scene) -> codegen (generate_c)
    -> build (cffi module, cache) -> solve (simulate) -> result (Result)

Quick start::

    import lagcodegen as lcg
    model = lcg.systems.pendulum()
    sim = lcg.compile_model(model, outputs=["energy"])
    res = sim.simulate([0, 10], q0=[1.0])
    res["theta"], res["energy"]
"""

from __future__ import annotations

__version__ = "0.1.0"

from .errors import (CompileError, DerivationError, LagcodegenError, ModelError,  # noqa: F401
                     SingularMassMatrixError, SolverError)
from .model import Model  # noqa: F401
from .derivation import EquationsOfMotion, derive  # noqa: F401
from .scene import Scene  # noqa: F401
from .codegen import GeneratedCode, generate_c, generate_code  # noqa: F401
from .fortran import generate_fortran  # noqa: F401
from .build import CompiledModel, build  # noqa: F401
from .bundle import render_bundle, write_bundle  # noqa: F401
from .solve import simulate  # noqa: F401
from .result import Result  # noqa: F401
from .constraints import ConstrainedSystem  # noqa: F401
from .dae import compile_constrained  # noqa: F401
from .events import Event, simulate_with_switch  # noqa: F401
from .routhian import ignorable_coordinates, reduce as routh_reduce  # noqa: F401
from .steady import steady_motions  # noqa: F401
from .linearize import linearize  # noqa: F401
from . import constraints, dae, energy, events, forces, routhian, steady  # noqa: F401
from . import systems  # noqa: F401

#: compile_model emits the analytic Jacobian by default up to this many coordinates: its C
#: compile time grows much faster than n (2 s at n = 10, 20 s at n = 20 with gcc -O2), while
#: CVODE's difference quotients cost only 2n right-hand sides per (rare) Jacobian update.
AUTO_JACOBIAN_MAX_N = 8


def compile_model(model: Model, *, jacobian: bool | None = None, outputs=(), runtime_parameters=None,
                  values=None, prefix: str | None = None, native: bool = True,
                  verbose: bool = False, lang: str = "c") -> CompiledModel:
    """Derive, generate and compile ``model`` in one call (see :class:`Scene` for the options;
    ``lang``: "c" or "fortran", the language of the generated model code).

    ``jacobian=None`` emits the analytic Jacobian for models with at most
    :data:`AUTO_JACOBIAN_MAX_N` coordinates; larger ones use CVODE's difference quotients.
    """
    if jacobian is None:
        jacobian = model.n <= AUTO_JACOBIAN_MAX_N
    scene = Scene(derive(model), jacobian=jacobian, outputs=outputs, runtime_parameters=runtime_parameters,
                  values=values or {}, prefix=prefix)
    return build(generate_code(scene, lang), native=native, verbose=verbose)
