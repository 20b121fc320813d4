"""lagcodegen: Lagrangian mechanics -> standalone C and Fortran code -> SUNDIALS integration.

The pipeline, one subpackage per stage, imports running one way (down this list):

    model (Model, model files in modelfile) -> derivation (derive) -> theory (energy, forces,
    Routhian, steady motion, linearization, constraints, minimal coordinates) -> formulation
    (Scene, language-neutral kernels) -> codegen (C, Fortran, cffi declarations, bundles)
    -> build (cffi module, cache) -> fmu (FMU export) -> solvers (CVODE, IDA, Taylor; scikit-sundae)
    -> simulation (compiled ODE, constrained and minimal faces, hybrid runs) -> sweep -> fitting
    (parameters from measured trajectories, with sensitivities) -> api -> cli

Quick start::

    import lagcodegen as lcg
    model = lcg.systems.pendulum()
    sim = lcg.compile_model(model, outputs=["energy"])
    res = sim.simulate([0, 10], q0=[1.0])
    res["theta"], res["energy"]
"""

from __future__ import annotations

from .version import __version__  # noqa: F401
from .errors import (CompileError, DerivationError, LagcodegenError, ModelError,  # noqa: F401
                     SingularMassMatrixError, SolverError)
from .model import systems  # noqa: F401
from .model.model import Model  # noqa: F401
from .model.bodies import Joint, Link, Placement  # noqa: F401
from .model.events import Event  # noqa: F401
from .derivation import EquationsOfMotion, derive  # noqa: F401
from .theory.constraints import ConstrainedSystem, Inequality, ground_contact  # noqa: F401
from .simulation.constrained_impacts import ContactOptions, PainleveError  # noqa: F401
from .theory.routhian import ignorable_coordinates, reduce as routh_reduce  # noqa: F401
from .theory.steady import steady_motions  # noqa: F401
from .theory.linearize import linearize  # noqa: F401
from .formulation.scene import Scene  # noqa: F401
from .codegen import GeneratedCode, generate_c, generate_code, generate_fortran  # noqa: F401
from .codegen.bundle import render_bundle, write_bundle  # noqa: F401
from .result import Result  # noqa: F401
from .solvers.registry import CVODE, IDA, Taylor  # noqa: F401
from .solvers.family import Sensitivities  # noqa: F401
from .solvers.inputs import Table  # noqa: F401
from .simulation.ode import CompiledModel, simulate  # noqa: F401
from .simulation.hybrid import simulate_with_switch  # noqa: F401
from .fitting import FitResult, fit  # noqa: F401
from .api import (AUTO_JACOBIAN_MAX_N, build_code, compile_constrained, compile_file,  # noqa: F401
                  compile_model, compile_reduction, compile_urdf, generate_file, run_sweep)
from . import modelfile, progress  # noqa: F401
from .fmu import export_fmu  # noqa: F401
from .modelfile import urdf  # noqa: F401  (the URDF reader, lagcodegen.modelfile.urdf)
