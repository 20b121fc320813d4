"""The public entry points: from a model (or a reduction, a constrained system, a model file)
to a compiled simulation in one call. Each runs the pipeline model -> derivation -> formulation
-> codegen -> build -> solvers; nothing below this module imports it.
"""

from __future__ import annotations

from typing import Any, Iterable, Mapping, Sequence

from . import build as _build
from . import hooks
from . import progress as _progress
from .codegen.languages import check_language, generate_code
from .codegen.constrained import generate_constrained
from .codegen.record import GeneratedCode
from .derivation import derive
from .errors import ModelError
from .formulation.constrained import DEFAULT_OUTPUTS
from .formulation.scene import Scene
from .model.mechanics import as_model
from .model.model import Model
from .modelfile.loader import constrained_outputs
from .solvers.compiled import CompiledModel
from .solvers.constrained import ConstrainedSimulation
from .solvers.minimal import MinimalSimulation
from .theory.constraints import FORMULATIONS, ConstrainedSystem
from .theory.routhian import RouthReduction
from .util import check_baumgarte

#: compile_model emits the analytic Jacobian by default up to this many coordinates. Measured
#: (benchmarks/scaling.py, n-link pendulum, BDF to rtol 1e-8): from n = 10 to 100 it makes a run
#: 0.3-1.1x as long as with CVODE's difference quotients but the build 1.2-5x as long (n = 10:
#: build 1.2 s against 0.5 s, run 1.6 ms against 1.9 ms), so a first run pays for it nowhere there.
AUTO_JACOBIAN_MAX_N = 8


def build(code: GeneratedCode, native: bool = True, cc: str | None = None,
          cflags: tuple[str, ...] = _build.DEFAULT_CFLAGS, verbose: bool = False,
          fc: str | None = None, fflags: tuple[str, ...] = _build.DEFAULT_FFLAGS) -> CompiledModel:
    """Compile ``code`` (:func:`lagcodegen.build.build`: cffi module, native CVODE driver, cache)
    and wrap it as a :class:`CompiledModel` ready to simulate."""
    return CompiledModel.from_built(_build.build(code, native=native, cc=cc, cflags=cflags, verbose=verbose,
                                                 fc=fc, fflags=fflags))


def compile_model(model: Model, *, jacobian: bool | None = None, outputs=(), runtime_parameters=None,
                  values=None, prefix: str | None = None, native: bool = True,
                  verbose: bool = False, lang: str = "c", progress=None) -> CompiledModel:
    """Derive, generate and compile ``model`` in one call (see :class:`Scene` for the options;
    ``lang``: "c" or "fortran", the language of the generated model code).

    ``model`` may be a ``sympy.physics.mechanics.System`` whose speeds are q'
    (:func:`lagcodegen.mechanics.from_system`); ``values`` then gives every parameter's value.

    ``jacobian=None`` emits the analytic Jacobian for models with at most
    :data:`AUTO_JACOBIAN_MAX_N` coordinates; larger ones use CVODE's difference quotients.

    ``progress``: True draws a line on stderr naming the stage and how far it is (derive,
    formulate, cse, compile) once a stage lasts a second; a callable is called as
    ``progress(stage, done, total, elapsed)``; False nothing; None (default) as the caller's
    :func:`lagcodegen.progress.enabled` says (off unless set).
    """
    model = as_model(model, parameters=values)  # a sympy.physics.mechanics.System: its values are needed
    with _progress.enabled(progress):
        if jacobian is None:
            jacobian = model.n <= AUTO_JACOBIAN_MAX_N
        scene = Scene(derive(model), jacobian=jacobian, outputs=outputs, runtime_parameters=runtime_parameters,
                      values=values or {}, prefix=prefix)
        return build(generate_code(scene, lang), native=native, verbose=verbose)


def compile_reduction(reduction: RouthReduction, outputs: Sequence[str] = ("jacobi_h",), *, jacobian: bool = True,
                      runtime_parameters: Sequence[str] | None = None, values: Mapping[str, float] | None = None,
                      prefix: str | None = None, native: bool = True, verbose: bool = False) -> CompiledModel:
    """Generate and build a Routhian-reduced system (eqs. 3.8-3.12; :meth:`RouthReduction.compile`).

    The integrals C_i always stay run-time parameters. The outputs ``<q_i>_dot`` (the
    ignorable velocities, eq. 3.11) come first, then ``outputs``; ``jacobi_h`` is the
    conserved h of eq. 3.12.
    """
    if runtime_parameters is not None:
        runtime_parameters = list(runtime_parameters)
        runtime_parameters += [C.name for C in reduction.integrals if C.name not in runtime_parameters]
    rates = [f"{q.name}_dot" for q in reduction.ignorable]
    scene = Scene(reduction.eom, jacobian=jacobian, outputs=rates + [o for o in outputs if o not in rates],
                  runtime_parameters=runtime_parameters, values=dict(values or {}), prefix=prefix)
    return build(generate_code(scene, "c"), native=native, verbose=verbose)


def compile_constrained(system: ConstrainedSystem, formulation: str = "index1", outputs: Sequence[str] | None = None,
                        baumgarte: tuple[float, float] | str = "auto", projection: bool = False,
                        events: Iterable = (), runtime_parameters=None, values: Mapping | None = None,
                        prefix: str | None = None, jacobian: bool = True, eliminate: Sequence | None = None,
                        verbose: bool = False, lang: str = "c", progress=None):
    """Generate and compile a constrained system (eq. 4.5) in one formulation.

    ``index1`` and ``ggl`` compile only the system's own code (model, ``<prefix>_dae.c`` or
    ``.f90``, and its function tables) into a library without Python.h; the native drivers
    (index 1 on CVODE, GGL on IDA) are the model-independent runtime's
    (:func:`lagcodegen.build.runtime`, compiled once per installation).

    Parameters
    ----------
    formulation:
        ``"index1"`` (CVODE, augmented system solved in C, Baumgarte and/or projection),
        ``"ggl"`` (IDA, stabilized index 2) or ``"minimal"`` (symbolic elimination).
    outputs:
        Output names: groups ``lambda`` (lambda_<j>), ``constraint_forces`` (R_<j>_<q> =
        lambda_j A_j), ``residuals`` (g_<j>, gdot_<j>), ``inequalities`` (ineq_<k>) and the
        model's (``energy``, ``positions``, ``momenta``, ...). Default: energy, lambda,
        residuals (minimal: energy, residuals, plus the eliminated coordinates).
    baumgarte:
        Default Baumgarte stabilization of the index-1 formulation (eq. 4.5 with f'' + 2 alpha f' +
        beta^2 f = 0): ``"auto"`` (default) takes alpha = beta = the rate of the system's fastest
        motion at each run's initial state (``<prefix>_natural_rate``: the diagonal of the index-1
        Jacobian, in 1/time, so it follows the model's time unit), none with projection;
        (alpha, beta) fixed values; (0, 0) none. simulate() may override. The choice is measured
        in benchmarks/bari.py (README, "Constrained systems").
    projection:
        Default for projection onto the constraints after each CVODE step (index-1 only).
    events:
        :class:`~lagcodegen.events.Event` items (name, expression, direction, terminal); the
        expressions may use ``lambda_<j>``. Inequality constraints are added as events.
    jacobian:
        GGL: generate the residual Jacobian dF/dy + cj dF/dy' (else IDA's difference quotients).
    eliminate:
        Minimal: coordinates to eliminate (default: the first subset sympy can solve for,
        trying the last coordinates first).
    lang:
        Language of the generated model functions: ``"c"`` or ``"fortran"`` (Fortran 2008
        modules bound to the same C names, evaluating the same operations, so the results are
        the C version's to the last bit where neither compiler contracts multiply-adds; the
        native CVODE/IDA drivers are C in both cases and call them through the same function
        table).
        The minimal formulation is C only.
    progress:
        As :func:`compile_model`'s: True a progress line on stderr, a callable
        ``progress(stage, done, total, elapsed)``, False nothing, None the caller's setting.
    """
    with _progress.enabled(progress):
        return _compile_constrained(system, formulation, outputs, baumgarte, projection, events, runtime_parameters,
                                    values, prefix, jacobian, eliminate, verbose, lang)


def _compile_constrained(system, formulation, outputs, baumgarte, projection, events, runtime_parameters, values,
                         prefix, jacobian, eliminate, verbose, lang):
    if not isinstance(system, ConstrainedSystem):
        raise ModelError(f"compile_constrained needs a ConstrainedSystem, got {type(system).__name__}")
    if formulation not in FORMULATIONS:
        raise ModelError(f"formulation must be one of {', '.join(FORMULATIONS)}, got {formulation!r}")
    baumgarte = check_baumgarte(baumgarte, "baumgarte")
    check_language(lang)
    if formulation == "minimal":
        return MinimalSimulation(system, outputs=outputs, events=events, runtime_parameters=runtime_parameters,
                                 values=values, prefix=prefix, eliminate=eliminate, verbose=verbose, lang=lang)
    if outputs is None:
        outputs = DEFAULT_OUTPUTS
    code, info = generate_constrained(system, ggl=formulation == "ggl", ggl_jacobian=jacobian, outputs=outputs,
                                      events=events, runtime_parameters=runtime_parameters, values=values,
                                      prefix=prefix, lang=lang)
    cm = build(code, native=True, verbose=verbose)
    return ConstrainedSimulation(system, formulation, cm, info, baumgarte, bool(projection))




def compile_file(mf, **options: Any):
    """Compile a loaded model file (:meth:`lagcodegen.modelfile.ModelFile.compile`) with its
    scene settings (``options`` override): :func:`compile_model`, or with constraints
    :func:`compile_constrained` with the file's formulation, Baumgarte parameters, projection,
    events and outputs (:func:`lagcodegen.modelfile.constrained_outputs`)."""
    s = mf.simulation
    if mf.constrained is not None:
        formulation = options.pop("formulation", s.formulation or "index1")
        copts: dict[str, Any] = dict(
            formulation=formulation, outputs=constrained_outputs(mf.constrained, s.outputs, formulation),
            events=list(mf.events), runtime_parameters=s.runtime_parameters, values=dict(s.parameters),
            jacobian=s.jacobian)
        if formulation == "index1":
            copts.update(baumgarte=s.baumgarte, projection=s.projection)
        copts.update(options)
        return compile_constrained(mf.constrained, **copts)
    kwargs: dict[str, Any] = dict(jacobian=s.jacobian, outputs=list(s.outputs),
                                  runtime_parameters=s.runtime_parameters, values=dict(s.parameters))
    kwargs.update(options)
    return compile_model(mf.model, **kwargs)


hooks.register("compile_reduction", compile_reduction)
hooks.register("compile_file", compile_file)
