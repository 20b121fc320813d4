"""lagcodegen: Lagrangian mechanics -> standalone C and Fortran code -> SUNDIALS integration.

The pipeline, one subpackage per stage, imports running one way (down this list):

    model (Model, model files in modelfile) -> derivation (derive) -> theory (energy, forces,
    Routhian, steady motion, linearization, constraints, minimal coordinates) -> formulation
    (Scene, language-neutral kernels) -> codegen (C, Fortran, cffi declarations, bundles)
    -> build (cffi module, cache) -> solvers (CVODE, IDA, scikit-sundae, hybrid) -> api -> cli

Quick start::

    import lagcodegen as lcg
    model = lcg.systems.pendulum()
    sim = lcg.compile_model(model, outputs=["energy"])
    res = sim.simulate([0, 10], q0=[1.0])
    res["theta"], res["energy"]
"""

from __future__ import annotations

import sys as _sys

from .version import __version__  # noqa: F401
from .errors import (CompileError, DerivationError, LagcodegenError, ModelError,  # noqa: F401
                     SingularMassMatrixError, SolverError)
from .model import events, mechanics, outputs, systems  # noqa: F401
from .model.model import Model  # noqa: F401
from .model.bodies import Joint, Link, Placement  # noqa: F401
from .model.events import Event  # noqa: F401
from .derivation import EquationsOfMotion, derive  # noqa: F401
from .theory import constraints, energy, forces, linearize as _linearize_module, minimal, routhian, steady  # noqa: F401
from .theory.constraints import ConstrainedSystem  # noqa: F401
from .theory.routhian import ignorable_coordinates, reduce as routh_reduce  # noqa: F401
from .theory.steady import steady_motions  # noqa: F401
from .theory.linearize import linearize  # noqa: F401
from .formulation import scene  # noqa: F401
from .formulation.scene import Scene  # noqa: F401
from .codegen import GeneratedCode, generate_c, generate_code, generate_fortran  # noqa: F401
from .codegen import bundle, fortran  # noqa: F401
from .codegen.bundle import render_bundle, write_bundle  # noqa: F401
from . import build as _build_module  # noqa: F401
from .result import Result  # noqa: F401
from .solvers.compiled import CompiledModel  # noqa: F401
from .solvers.hybrid import simulate_with_switch  # noqa: F401
from .solvers.ode import simulate  # noqa: F401
from .solvers.options import CVODE, IDA, Taylor  # noqa: F401
from .api import (AUTO_JACOBIAN_MAX_N, build, compile_constrained, compile_model,  # noqa: F401
                  compile_reduction)
from . import modelfile  # noqa: F401
from .modelfile import urdf  # noqa: F401

from . import legacy as _legacy  # noqa: E402

# The module paths of lagcodegen 0.1 (``from lagcodegen.dae import compile_constrained``, ...).
_legacy.install(_sys.modules[__name__])
dae = _sys.modules[f"{__name__}.dae"]
# lagcodegen.urdf is lagcodegen.modelfile.urdf (``import lagcodegen.urdf`` works too).
_sys.modules.setdefault(f"{__name__}.urdf", urdf)
