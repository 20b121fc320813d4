"""The public entry points: from a model (or a reduction, a constrained system, a model file)
to a compiled simulation in one call, the sources of a model file, and a sweep over a model
file. Each runs the pipeline model -> derivation -> formulation -> codegen -> build -> solvers -> simulation;
nothing below this module imports it, and the command line (:mod:`lagcodegen.cli`) calls only
these functions to run a pipeline.

One job: the entry points, each the whole pipeline in one call, with the pipeline cache's keys of
what they compile (the cache itself: :func:`lagcodegen.cache.cached_code`).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

import numpy as np

from . import build as _build
from . import progress as _progress
from . import sweep as _sweep
from .buildstep import load_source
from .cache import cached_code, pipeline_key
from .codegen.bundle import REFERENCE_ATOL, REFERENCE_RTOL, ExampleRun, register_reference_run, render_bundle, \
    render_constrained_bundle
from .codegen.languages import backend, check_language, generate_code
from .codegen.constrained import generate_constrained
from .codegen.events import events_source
from .codegen.record import CachedCode, GeneratedCode
from .derivation import EquationsOfMotion, derive
from .errors import ModelError
from .formulation.constrained import DEFAULT_OUTPUTS
from .formulation.events import scene_events
from .formulation.scene import Scene
from .model.mechanics import as_model
from .model.canonical import canonical_form
from .model.model import Model, require_model
from .modelfile import ModelFile, constrained_outputs, load_model_path
from .simulation.constrained import ConstrainedSimulation
from .simulation.minimal import MinimalSimulation
from .simulation.ode import CompiledModel, pickle_code
from .theory.constraints import FORMULATIONS, ConstrainedSystem
from .theory.minimal import closest_branch, reduced_model, solve_constraints
from .simulation.speeds import IndependentSpeedsSimulation
from .theory.routhian import RouthReduction
from .util import check_baumgarte, excerpt

#: compile_model emits the analytic Jacobian by default up to this many coordinates; above, the
#: longer build outweighs the faster runs of a first run (measured in benchmarks/scaling.py; the
#: figures in README.md, "Notes on the solvers").
AUTO_JACOBIAN_MAX_N = 8


def build_code(code: GeneratedCode, native: bool = True, cc: str | None = None,
               cflags: tuple[str, ...] = _build.DEFAULT_CFLAGS, verbose: bool = False,
               fc: str | None = None, fflags: tuple[str, ...] = _build.DEFAULT_FFLAGS) -> CompiledModel:
    """Compile ``code`` (:func:`lagcodegen.build.build`: the model's library, the cffi module,
    the cache) and wrap it as a :class:`CompiledModel` ready to simulate."""
    return CompiledModel.from_built(_build.build(code, native=native, cc=cc, cflags=cflags, verbose=verbose,
                                                 fc=fc, fflags=fflags))


def compile_model(model: Model, *, jacobian: bool | None = None, outputs=(), runtime_parameters=None,
                  values=None, prefix: str | None = None, native: bool = True,
                  verbose: bool = False, lang: str = "c", progress=None) -> CompiledModel:
    """Derive, generate and compile ``model`` in one call (see :class:`Scene` for the options;
    ``lang``: "c" or "fortran", the language of the generated model code).

    ``model`` may be a ``sympy.physics.mechanics.System`` (:func:`lagcodegen.model.mechanics.from_system`)
    or a ``KanesMethod`` after ``kanes_equations`` (:func:`~lagcodegen.model.mechanics.from_kanes_method`);
    ``values`` then gives every parameter's value.

    ``jacobian=None`` emits the analytic Jacobian for models with at most
    :data:`AUTO_JACOBIAN_MAX_N` coordinates; larger ones use CVODE's difference quotients.

    ``progress``: True draws a line on stderr naming the stage and how far it is (derive,
    formulate, cse, compile) once a stage lasts a second; a callable is called as
    ``progress(stage, done, total, elapsed)``; False nothing; None (default) as the caller's
    :func:`lagcodegen.progress.enabled` says (off unless set). A build that really runs is the
    outer stage ``build model '<name>' (not cached)``; a model from the cache reports nothing.

    The pipeline cache: the generated code is kept in the build cache under a key of the model's
    canonical form (:func:`lagcodegen.model.canonical.canonical_form`: coordinates, parameters
    and their defaults, points, bodies, links and joints, energies, forces, outputs, inputs, in
    declaration order, every expression as ``sympy.srepr``), these options (but ``native`` and
    ``verbose``) and the generator record (lagcodegen's sources, sympy, symengine): compiling an
    equal model again, in this process or a new one, loads the code and its library without
    deriving or generating anything; any change of the model is another key. The returned
    model's scene is then derived again only when a run needs it (the Taylor method, events,
    sensitivities, a drawing, reading ``code.scene``). A model with a part that has no canonical
    form (a sympy function implemented in Python or a ``Function`` subclass of the user's, an
    object of a class other than the model's own) is not cached: it is derived and generated
    every time, never a wrong hit.
    """
    converted = require_model(as_model(model, parameters=values), "compile_model")  # a System: its values are needed
    if converted is not model and values:  # sympy's objects take values by symbol too: the scene's are by name
        values = {getattr(k, "name", k): v for k, v in values.items()}
    model = converted
    with _progress.enabled(progress):
        return _compile_cached_model(model, derive, jacobian=jacobian, outputs=outputs,
                                     runtime_parameters=runtime_parameters, values=values, prefix=prefix,
                                     native=native, verbose=verbose, lang=lang)


def _compile_cached_model(model: Model, derive_model: Callable[[Model], EquationsOfMotion], *, jacobian, outputs,
                          runtime_parameters, values, prefix, native: bool, verbose: bool, lang: str):
    """:func:`_compile_equations` of ``derive_model(model)`` through the pipeline cache, keyed by
    the model's canonical form (:func:`lagcodegen.model.canonical.canonical_form`) and these
    options; a model without one (a Python-defined sympy function, a foreign object) is derived
    and generated every time, never cached. A model from the cache re-derives its scene when a
    run needs it (``code.rederive``)."""
    options = dict(jacobian=jacobian, outputs=list(outputs or ()), runtime_parameters=runtime_parameters,
                   values=dict(values or {}), prefix=prefix, lang=lang)
    described, chosen = canonical_form(model), canonical_form(options)

    def scene() -> Scene:
        eom = derive_model(model)
        return Scene(eom, jacobian=auto_jacobian(eom) if jacobian is None else jacobian, outputs=outputs or (),
                     runtime_parameters=runtime_parameters, values=dict(values or {}), prefix=prefix)

    if described is None or chosen is None:
        return build_code(generate_code(scene(), lang), native=native, verbose=verbose)

    def make():
        code = generate_code(scene(), lang)
        return code, pickle_code(code)

    def build(code: GeneratedCode, cached: bool):
        return build_code(CachedCode.of(code, scene) if cached else code, native=native, verbose=verbose)

    key = pipeline_key("model-code", described, chosen)
    return cached_code(key, f"model {model.name!r}", make, build)


def compile_urdf(path: str | os.PathLike, *, load: Mapping[str, Any] | None = None, limits: Any = None,
                 jacobian: bool | None = None, outputs: Sequence[str] | None = None, runtime_parameters=None,
                 values=None, prefix: str | None = None, native: bool = True, progress=None):
    """``compile_model(urdf.load(path, **load), ...)`` with its generated code cached by the URDF
    file's content: a new process that compiles the same file with the same options loads the code
    and the compiled library from the cache without deriving anything (``lagcodegen simulate`` on
    a .urdf file goes through it too).

    ``load``: the keywords of :func:`lagcodegen.modelfile.urdf.load` (``floating``, ``mimic``,
    ``lock``, ``gravity``, ``friction``, ``form``, ``name``, ``limits``, ...); the others as
    :func:`compile_model` (C only). The cache key is the file's bytes, these options, and the
    versions of lagcodegen (its sources' digest), sympy and symengine. A model from the cache has
    no symbolic scene until a run needs one (the Taylor method, events, sensitivities, a drawing):
    it is then derived again from the file, once.

    ``limits`` (the same as ``load={"limits": ...}``): True or ``"stop"`` makes each joint limit
    a hard stop, a unilateral contact g >= 0 (eq. 4.3) with a plastic impact, ``("stop", e)`` one
    with restitution e, ``"monitor"`` an inequality located as an event only. The URDF is then a
    constrained system and the result :func:`compile_constrained`'s (formulation ``index1``, the
    impact driver of :mod:`lagcodegen.simulation.constrained_impacts`; cached by the file as
    well): runs go on through impacts, rest at a limit with its multiplier as the output
    ``lambda_ineq_<k>`` and leave it where that multiplier would pull; ``Result.impacts`` logs each
    impact, rest and release. Contact k is row k of ``system.inequalities``: the lower limit
    (q - lower) of each limited joint, then its upper limit (upper - q), in the tree's order.
    ``outputs`` default: none for a model, :func:`compile_constrained`'s default for a constrained
    system; ``jacobian`` applies to models only (the index-1 formulation has none).
    """
    import hashlib

    from .modelfile import urdf as _urdf
    from .modelfile import urdfxml as _urdfxml

    load = dict(load or {})
    if limits is not None:
        if "limits" in load and load["limits"] != limits:
            raise ModelError(f"compile_urdf: limits={excerpt(limits)} and load={{'limits': "
                             f"{excerpt(load['limits'])}}} disagree: give one")
        load["limits"] = limits
    data = _urdfxml.read_bytes(path, max_bytes=load.get("max_bytes", _urdfxml.MAX_BYTES))
    digest = hashlib.sha256(data).hexdigest()
    options = dict(jacobian=jacobian, outputs=None if outputs is None else list(outputs),
                   runtime_parameters=runtime_parameters, values=dict(values or {}), prefix=prefix)
    key = pipeline_key("urdf-code", digest, repr(sorted(load.items())), repr(sorted(options.items())))

    def described() -> Model | ConstrainedSystem:
        return _urdf.loads(data, filename=str(path), **load)

    def scene(model: Model | None = None) -> Scene:
        eom = derive(described() if model is None else model)
        return Scene(eom, jacobian=auto_jacobian(eom) if jacobian is None else jacobian,
                     outputs=outputs or (), runtime_parameters=runtime_parameters, values=dict(values or {}),
                     prefix=prefix)

    def constrained_code(system: ConstrainedSystem):
        check_native()
        return generate_constrained(system, outputs=DEFAULT_OUTPUTS if outputs is None else outputs,
                                    runtime_parameters=runtime_parameters, values=values, prefix=prefix)

    def check_native() -> None:
        if not native:
            raise ModelError(f"{path}: with limits (or mimic='coupled') the URDF is a constrained system, which "
                             "runs on the native drivers only: native=True")

    def make():
        model = described()
        if isinstance(model, ConstrainedSystem):
            code, info = constrained_code(model)
            return (code, info, model), (pickle_code(code), info, model)
        code = generate_code(scene(model), "c")
        return code, pickle_code(code)

    def build(entry, cached: bool):
        if isinstance(entry, tuple):  # a constrained system: (code, info, system)
            code, info, system = entry
            check_native()
            if cached:
                code = CachedCode.of(code, lambda: constrained_code(described())[0].scene)
            return ConstrainedSimulation(system, "index1", build_code(code, native=True), info,
                                         check_baumgarte("auto", "baumgarte"), False)
        return build_code(CachedCode.of(entry, scene) if cached else entry, native=native)

    with _progress.enabled(progress):
        return cached_code(key, f"URDF {Path(path).name}", make, build)


def auto_jacobian(eom: EquationsOfMotion) -> bool:
    """``jacobian=None``: the analytic Jacobian for models of at most AUTO_JACOBIAN_MAX_N
    coordinates (with generalized speeds too: the coordinates q, nq of them) whose mass matrix is
    symmetric."""
    return getattr(eom, "symmetric", True) and eom.model.n <= AUTO_JACOBIAN_MAX_N


def _compile_equations(eom: EquationsOfMotion, *, jacobian: bool | None, outputs, runtime_parameters, values,
                       prefix: str | None, native: bool, verbose: bool, lang: str) -> CompiledModel:
    if jacobian is None:
        jacobian = auto_jacobian(eom)
    scene = Scene(eom, jacobian=jacobian, outputs=outputs, runtime_parameters=runtime_parameters,
                  values=values or {}, prefix=prefix)
    return build_code(generate_code(scene, lang), native=native, verbose=verbose)


def compile_reduction(reduction: RouthReduction, outputs: Sequence[str] = ("jacobi_h",), *, jacobian: bool = True,
                      runtime_parameters: Sequence[str] | None = None, values: Mapping[str, float] | None = None,
                      prefix: str | None = None, native: bool = True, verbose: bool = False) -> CompiledModel:
    """Generate and build a Routhian-reduced system (eqs. 3.8-3.12) for
    :meth:`RouthReduction.simulate <lagcodegen.theory.routhian.RouthReduction.simulate>`.

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
    return build_code(generate_code(scene, "c"), native=native, verbose=verbose)


def compile_constrained(system: ConstrainedSystem, formulation: str = "index1", *,
                        outputs: Sequence[str] | None = None, events: Iterable = (), runtime_parameters=None,
                        values: Mapping | None = None, prefix: str | None = None, lang: str = "c",
                        verbose: bool = False, progress=None, **options):
    """Generate and compile a constrained system (eq. 4.5) in one formulation.

    ``options`` are the formulation's own (:data:`FORMULATION_OPTIONS`): ``baumgarte`` and
    ``projection`` (index1), ``jacobian`` (ggl; accepted by every formulation, the others generate
    no Jacobian), ``eliminate`` (minimal); a name that is none of these, or an option given to a
    formulation that does not take it, raises ModelError naming it.

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
        :class:`~lagcodegen.model.events.Event` items (name, expression, direction, terminal); the
        expressions may use ``lambda_<j>``. Inequality constraints are added as events; contacts
        (:class:`~lagcodegen.theory.constraints.Inequality` with a restitution) are impacts instead
        (index1 only; :mod:`lagcodegen.simulation.constrained_impacts`).
    jacobian:
        GGL: generate the residual Jacobian dF/dy + cj dF/dy' (else IDA's difference quotients).
    eliminate:
        Minimal: coordinates to eliminate (default: the first subset sympy can solve for,
        trying the last coordinates first). With nonholonomic constraints, "minimal" is the
        system in independent speeds (:mod:`lagcodegen.theory.speeds`: Maggi's, Voronets' and
        Kane's form M_r = B^T M B, every constraint at velocity level:
        :class:`~lagcodegen.simulation.speeds.IndependentSpeedsSimulation`, state (q, u), the
        holonomic residuals ``g_<j>`` as outputs) and ``eliminate`` names the coordinates whose
        rates are eliminated (default: by column-pivoted QR of A at each run's initial state).
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

    The index-1 and GGL formulations are cached as :func:`compile_model` is: by the canonical
    form of the system (its model, constraints, inequalities with their restitutions, tangents
    and friction), the events, outputs, parameters, prefix, language and Jacobian option; the
    run-time options (``baumgarte``, ``projection``) are not part of the code and not of the key.
    The minimal formulation is derived every time.
    """
    with _progress.enabled(progress):
        if not isinstance(system, ConstrainedSystem):
            raise ModelError(f"compile_constrained needs a ConstrainedSystem, got {type(system).__name__}")
        if formulation not in FORMULATIONS:
            raise ModelError(f"formulation must be one of {', '.join(FORMULATIONS)}, got {excerpt(formulation)}")
        o = formulation_options(formulation, options)
        return _compile_constrained(system, formulation, o, outputs, events, runtime_parameters, values, prefix,
                                    verbose, lang)


#: The options of each constrained formulation with their defaults (``compile_constrained(**options)``).
FORMULATION_OPTIONS = {"baumgarte": ("auto", ("index1",)), "projection": (False, ("index1",)),
                       "jacobian": (True, FORMULATIONS), "eliminate": (None, ("minimal",))}


def formulation_options(formulation: str, options: Mapping) -> dict:
    """Every option of :data:`FORMULATION_OPTIONS`, from ``options`` or its default; ModelError
    for an unknown name or one ``formulation`` does not take (given a value other than the default)."""
    unknown = [k for k in options if k not in FORMULATION_OPTIONS]
    if unknown:
        raise ModelError(f"compile_constrained: unknown option{'s' if len(unknown) > 1 else ''} "
                         f"{', '.join(map(repr, unknown))} (options: {', '.join(FORMULATION_OPTIONS)})")
    out = {}
    for name, (default, takes) in FORMULATION_OPTIONS.items():
        value = options.get(name, default)
        if formulation not in takes and value is not default and value != default:
            raise ModelError(f"compile_constrained: {name}={excerpt(value)} does not apply to formulation "
                             f"{formulation!r} "
                             f"({', '.join(takes)} only)")
        out[name] = value
    return out


def _independent_speeds(system, eliminate, outputs, events, runtime_parameters, values, prefix, verbose, lang):
    """A system with nonholonomic constraints in minimal form: the compiled model of its
    independent speeds (:func:`lagcodegen.theory.speeds.independent_speeds_model`; ``eliminate``:
    the coordinates whose rates are eliminated, default chosen by pivoting), state (q, u), the
    holonomic constraints' residuals g_<j> among the outputs."""
    if events:
        raise ModelError("compile_constrained: formulation 'minimal' of a system with nonholonomic constraints "
                         "compiles an ODE in independent speeds: give its events to simulate(..., events=...)")
    independent = None
    if eliminate is not None:
        gone = {system.model.coords[system.model.index(q)].name for q in eliminate}
        independent = [q.name for q in system.model.coords if q.name not in gone]
    return IndependentSpeedsSimulation(system, independent=independent, outputs=outputs,
                                       runtime_parameters=runtime_parameters, values=values, prefix=prefix,
                                       verbose=verbose, lang=lang)


def _compile_constrained(system, formulation, options: dict, outputs, events, runtime_parameters, values, prefix,
                         verbose, lang, check=None):
    """The simulation of ``system`` in ``formulation`` with its ``options`` (those of
    :data:`FORMULATION_OPTIONS`, each given or defaulted by :func:`formulation_options`)."""
    model = system.model
    if model.general and formulation not in ("index1", "ggl"):
        raise ModelError(f"compile_constrained: model {model.name!r} has generalized speeds (nq = {model.nq}, "
                         f"nv = {model.nv}): its constrained forms are formulation='index1' (CVODE) and 'ggl' (IDA); "
                         f"formulation {formulation!r} does not take generalized speeds yet")
    projection, jacobian, eliminate = options["projection"], options["jacobian"], options["eliminate"]
    baumgarte = check_baumgarte(options["baumgarte"], "baumgarte")
    check_language(lang)
    if formulation == "minimal" and system.nonholonomic:  # independent speeds (Maggi, Voronets, Kane)
        return _independent_speeds(system, eliminate, outputs, events, runtime_parameters, values, prefix, verbose,
                                   lang)
    if formulation == "minimal":
        return MinimalSimulation(system, outputs=outputs, events=events, runtime_parameters=runtime_parameters,
                                 values=values, prefix=prefix, eliminate=eliminate, verbose=verbose, lang=lang)
    if outputs is None:
        outputs = DEFAULT_OUTPUTS
    events = list(events)

    def generate():
        if check is not None:
            check()
        return generate_constrained(system, ggl=formulation == "ggl", ggl_jacobian=jacobian, outputs=outputs,
                                    events=events, runtime_parameters=runtime_parameters, values=values,
                                    prefix=prefix, lang=lang)

    def make():
        code, info = generate()
        return (code, info), (pickle_code(code), info)

    def build(entry, cached: bool):
        code, info = entry
        if cached:
            code = CachedCode.of(code, lambda: generate()[0].scene)
        return ConstrainedSimulation(system, formulation, build_code(code, native=True, verbose=verbose), info,
                                     baumgarte, bool(projection))

    described = canonical_form(system, {ConstrainedSystem: constrained_fields})
    chosen = canonical_form(dict(formulation=formulation, jacobian=jacobian, outputs=list(outputs), events=events,
                                 runtime_parameters=runtime_parameters, values=dict(values or {}), prefix=prefix,
                                 lang=lang))
    if described is None or chosen is None:  # not cached: derived and generated every time
        return build(make()[0], False)
    return cached_code(pipeline_key("constrained-code", described, chosen), f"model {model.name!r} ({formulation})",
                        make, build)


def constrained_fields(system: ConstrainedSystem) -> list:
    """What a constrained system states, for its canonical form (its model and constraints)."""
    return [(name, getattr(system, name)) for name in (
        "model", "holonomic", "nonholonomic", "inequalities", "restitution", "tangents", "friction", "multipliers",
        "integrability_checked")]


# ---------------------------------------------------------------------- model files
def _model_file_argument(mf) -> ModelFile:
    """``mf`` itself if it is a ModelFile, the model file at it if it is a path
    (:func:`lagcodegen.modelfile.load_model_path`), else a ModelError saying what is taken."""
    if isinstance(mf, ModelFile):
        return mf
    if isinstance(mf, str) or hasattr(mf, "__fspath__"):
        return load_model_path(mf)
    hint = {"Model": ": for a Model, use compile_model(model)",
            "ConstrainedSystem": ": for a ConstrainedSystem, use compile_constrained(system)"}.get(type(mf).__name__, "")
    raise ModelError(f"compile_file takes a loaded model file (lagcodegen.modelfile.load_model_path) or a model "
                     f"file's path, got {'None' if mf is None else f'a {type(mf).__name__}'}{hint}")


def compile_file(mf: ModelFile | str | os.PathLike, **options: Any):
    """Compile a loaded model file (or the model file at a path: :func:`load_model_path`) with its
    ``[simulation]`` settings (``options`` override; run it with :meth:`ModelFile.simulate
    <lagcodegen.modelfile.ModelFile.simulate>`).

    Without constraints: :func:`compile_model` with the file's outputs, run-time parameters,
    parameter values and Jacobian setting. With constraints: :func:`compile_constrained` with the
    file's formulation, Baumgarte parameters, projection, events and outputs
    (:func:`lagcodegen.modelfile.constrained_outputs`). Errors of the derivation name the file
    and line (:meth:`ModelFile.derive <lagcodegen.modelfile.ModelFile.derive>`).

    The file's initial state (``[simulation] initial``) is the compiled system's default:
    ``simulate(t)`` (and ``integrator()``, ``fit``) without ``q0`` (or ``v0``) starts from the
    file's values, as the command line does; ``initial_defaults`` holds them as (q0, v0).

    Cached as :func:`compile_model` and :func:`compile_constrained` are: the key is the loaded
    model's canonical form (of the file's model, its constraints and events: whatever the file
    says, and any change made to the loaded ModelFile since), the options the file's settings
    and ``options`` give the compilation (outputs, run-time parameters, parameter values,
    Jacobian, formulation) and the generator record. A new process compiling an unchanged file
    reads the file (parsed, never executed) and loads the code and library from the cache
    without deriving; an edit that changes the model misses (one that does not, a comment or
    the integration settings, hits). Derivation errors still name the file and line: the model
    is derived before a build that really runs. The minimal formulation is not cached.
    """
    mf = _model_file_argument(mf)
    sim = _compile_file(mf, **options)
    sim.initial_defaults = mf.initial_state()
    return sim


def _compile_file(mf: ModelFile, **options: Any):
    """:func:`compile_file` but for the initial state's defaults."""
    s = mf.simulation
    with _progress.enabled(options.pop("progress", None)):
        if mf.constrained is not None:
            formulation = options.pop("formulation", None) or s.formulation or "index1"
            copts: dict[str, Any] = dict(
                formulation=formulation, outputs=constrained_outputs(mf.constrained, s.outputs, formulation),
                events=list(mf.events), runtime_parameters=s.runtime_parameters, values=dict(s.parameters),
                jacobian=s.jacobian)
            if formulation == "index1":
                copts.update(baumgarte=s.baumgarte, projection=s.projection)
            copts.update(options)
            # errors located in the file (derived before a build only; the system is derived again)
            return _compile_file_constrained(mf, copts)
        if options.pop("formulation", None) is not None:
            raise ModelError(f"{mf.path}: a formulation applies to model files with [constraints]")
        # generalized speeds (a floating URDF): no analytic Jacobian yet, CVODE's differences instead
        kwargs: dict[str, Any] = dict(jacobian=s.jacobian and not mf.model.general, outputs=list(s.outputs),
                                      runtime_parameters=s.runtime_parameters, values=dict(s.parameters),
                                      prefix=None, native=True, verbose=False, lang="c")
        kwargs.update(options)
        return _compile_cached_model(mf.model, lambda _model: mf.derive(), **kwargs)


def _compile_file_constrained(mf: ModelFile, copts: dict):
    """:func:`compile_constrained` of the file's system, which derives it first where a build
    runs, so that its errors name the file and line."""
    system, formulation = mf.constrained, copts.pop("formulation")
    if formulation not in FORMULATIONS:
        raise ModelError(f"formulation must be one of {', '.join(FORMULATIONS)}, got {excerpt(formulation)}")
    o = formulation_options(formulation, {k: copts.pop(k) for k in list(copts) if k in FORMULATION_OPTIONS})
    unknown = set(copts) - {"outputs", "events", "runtime_parameters", "values", "prefix", "lang", "verbose"}
    if unknown:
        return compile_constrained(system, formulation, **o, **copts)  # its error names the option
    if formulation == "minimal":
        mf.derive()
    return _compile_constrained(system, formulation, o, copts.get("outputs"), copts.get("events", ()),
                                copts.get("runtime_parameters"), copts.get("values"), copts.get("prefix"),
                                copts.get("verbose", False), copts.get("lang", "c"), check=mf.derive)


def _event_files(scene: Scene, mf: ModelFile, lang: str, report: Callable[[str], None] | None) -> dict[str, str]:
    """``<prefix>_events.c`` of the file's ``[[events]]`` (checked against the scene: ModelError
    naming a bad one), the C function ``int <prefix>_events(t, y, p, gout)`` the native drivers'
    root finding takes; none without events. Printed in C only: with ``lang`` "fortran" ``report``
    says so and nothing is added."""
    if not mf.events:
        return {}
    if not backend(lang).c_sources:
        if report is not None:
            report(f"{len(mf.events)} event function(s): printed in C only (generate with --lang c for "
                   f"{scene.prefix}_events.c)")
        return {}
    return events_source(scene, scene_events(scene, list(mf.events)))


def generate_file(mf: ModelFile, *, lang: str = "c", bundle: bool = False, method: str | None = None,
                  prefix: str | None = None, report: Callable[[str], None] | None = None,
                  sensitivities: bool = False) -> dict[str, str]:
    """The sources of a loaded model file (file name -> text) with its ``[simulation]`` settings
    (outputs, run-time parameters and values, Jacobian; constrained files: formulation,
    Baumgarte parameters, events), in ``lang`` ("c" or "fortran"), rendered in memory.

    Without constraints: the model code (:func:`lagcodegen.codegen.generate_code`). With
    constraints: the system's ``<prefix>_dae`` sources (index1, ggl), or in minimal coordinates
    the model code of the reduced model on the solution branch of the file's initial state
    (:func:`lagcodegen.theory.minimal.closest_branch`). ``bundle``: the self-contained folder
    (:func:`lagcodegen.codegen.bundle.render_bundle`: Makefile, CMakeLists.txt, examples, README)
    starting from the file's initial state; ``method``: its CVODE example's method (default
    "bdf"). ``report``, if given, is called with a line naming the branch chosen.
    ``sensitivities``: the bundle of an unconstrained (or minimal-coordinate) model carries the
    forward sensitivity functions too (:func:`~lagcodegen.codegen.bundle.render_bundle`).
    """
    check_language(lang)
    s = mf.simulation
    runtime = s.runtime_parameters
    values = dict(s.parameters)
    folded = {k: v for k, v in values.items() if runtime is not None and k not in runtime}
    q0, v0 = mf.initial_state()
    if mf.constrained is None:
        eom = mf.derive()
        scene = Scene(eom, jacobian=s.jacobian and not eom.general, outputs=list(s.outputs), runtime_parameters=runtime,
                      values=folded, prefix=prefix)
        code = generate_code(scene, lang)
        if not bundle:
            return {**code.files, **_event_files(scene, mf, lang, report)}
        params = {k: v for k, v in values.items() if k in scene.runtime_parameters}
        return render_bundle(scene, lang, y0=q0 + v0, params=params, t_start=s.t_start, t_end=s.t_end, code=code,
                             method=method or "bdf", sensitivities=sensitivities)
    system = mf.constrained
    mf.derive()  # errors located in the file
    formulation = s.formulation or "index1"
    outputs = constrained_outputs(system, s.outputs, formulation)
    values = {**{p.name: v for p, v in system.model.params.items()}, **values}
    params = {k: v for k, v in values.items() if runtime is None or k in runtime}
    if formulation == "minimal":
        scene, eliminated = _minimal_scene(mf, outputs, folded, prefix, report)
        code = generate_code(scene, lang)
        if not bundle:
            return dict(code.files)
        keep = [i for i, q in enumerate(system.model.coords) if q not in eliminated]
        return render_bundle(scene, lang, y0=[q0[i] for i in keep] + [v0[i] for i in keep],
                             params={k: v for k, v in params.items() if k in scene.runtime_parameters},
                             t_start=s.t_start, t_end=s.t_end, code=code, sensitivities=sensitivities)
    if sensitivities:
        raise ModelError(f"sensitivities of constrained systems in the {formulation} formulation are not generated "
                         "(formulation 'minimal' gives an ODE with them)")
    ggl = formulation == "ggl"
    if bundle:
        return render_constrained_bundle(system, lang, outputs=outputs, events=list(mf.events),
                                         runtime_parameters=runtime, values=folded, prefix=prefix, ggl=ggl,
                                         baumgarte=s.baumgarte if formulation == "index1" else (0.0, 0.0),
                                         example=ExampleRun(y0=q0 + v0, params=params, t_start=s.t_start,
                                                            t_end=s.t_end))
    code, _ = generate_constrained(system, ggl=ggl, ggl_jacobian=s.jacobian, outputs=outputs, events=list(mf.events),
                                   runtime_parameters=runtime, values=folded, prefix=prefix, lang=lang)
    files = {name: text for name, text in code.files.items() if name.startswith(f"{code.prefix}_dae.")}
    if system.contacts:  # the contact functions with their tables, and what they include and link to
        files.update({name: text for name, text in _build.dae_table_source(code).items()})
        # the constrained table points to the unconstrained model's table: that model and its table
        model_source = f"{code.prefix}{backend(lang).suffix}"
        files.update({name: code.files[name] for name in (model_source, f"{code.prefix}.h")})
        files.update(_build.table_source(code))
        # <prefix>_impact.c; in Fortran <prefix>_impact.f90 and its C tables <prefix>_impact_table.c
        files.update({name: text for name, text in code.files.items() if name.startswith(f"{code.prefix}_impact")})
        files["lcg_imp_model.h"] = code.files["lcg_imp_model.h"]
    return files


def _minimal_scene(mf: ModelFile, outputs: Sequence[str], folded: Mapping[str, float], prefix: str | None,
                   report: Callable[[str], None] | None) -> tuple[Scene, list]:
    """The Scene of the reduced model (minimal coordinates) on the branch of the file's initial
    state, and the eliminated coordinates."""
    system, s = mf.constrained, mf.simulation
    model = system.model
    if mf.events or system.inequalities:
        raise ModelError("minimal coordinates: events and inequality constraints need formulation 'index1' or 'ggl'")
    eliminated, branches = solve_constraints(system)
    q0, _ = mf.initial_state()
    values = {**{p.name: v for p, v in model.params.items()}, **s.parameters}
    b, error = closest_branch(system, eliminated, branches, q0, s.t_start, values)
    if not error <= 1e-8 * (1 + max(map(abs, q0))):
        raise ModelError(f"minimal coordinates: no solution branch of the constraints matches the initial state "
                         f"(closest differs by {error:.3g})")
    if report is not None:
        report(f"minimal coordinates: {', '.join(q.name for q in eliminated)} eliminated (branch {b}: "
               + ", ".join(f"{q.name} = {branches[b][q]}" for q in eliminated) + ")")
    red = reduced_model(system, branches[b], name=model.name)
    python_side = ("residuals", "inequalities")
    scene_outputs = [o for o in outputs if o not in python_side and not o.startswith(("g_", "gdot_"))]
    scene_outputs += [q.name for q in eliminated] + [f"{q.name}_dot" for q in eliminated]
    return Scene(derive(red), jacobian=s.jacobian, outputs=scene_outputs, runtime_parameters=s.runtime_parameters,
                 values=folded, prefix=prefix), eliminated


# ---------------------------------------------------------------------- sweeps
def run_sweep(spec: _sweep.SweepSpec, say: Callable[[str], None] | None = None) -> dict[str, np.ndarray]:
    """A whole sweep (:mod:`lagcodegen.sweep`): check the options, load the model file
    (:func:`lagcodegen.buildstep.load_source`), check the names, compile (:func:`compile_file`,
    every swept parameter a run-time parameter), run one ensemble and write the table (and the
    plot). Returns the table (column name -> (N,) array). ``say`` gets the progress lines
    (default: stderr unless ``spec.quiet``).

    Raises :class:`lagcodegen.sweep.SweepOptionError` on a bad option (before any work),
    :class:`~lagcodegen.errors.SolverError` when every member failed (after writing), and the
    ensemble's KeyboardInterrupt on Ctrl-C (writing nothing).
    """
    if say is None:
        def say(msg: str) -> None:
            if not spec.quiet:
                print(f"lagcodegen: {msg}", file=sys.stderr, flush=True)
    plan = _sweep.check_options(spec)
    t0 = time.perf_counter()
    mf = load_source(spec.model).model_file
    say(f"loaded {spec.model} ({mf.model.n} coordinates) in {time.perf_counter() - t0:.3f} s")
    _sweep.check_names(plan, mf)
    options, values = _sweep.compile_options(plan, mf)
    t0 = time.perf_counter()
    sim = compile_file(mf, **options)
    say(f"derived, generated and compiled in {time.perf_counter() - t0:.3f} s")
    return _sweep.run_plan(plan, mf, sim, values, say)


def _bundle_reference(scene: Scene, code: GeneratedCode | None, y: Sequence[float], p: Sequence[float],
                      t0: float, t1: float) -> tuple[list[str], list[float]]:
    """The reference row of a bundle's ``make check`` (:func:`lagcodegen.codegen.bundle.reference_values`):
    t, the state and the outputs of ``scene`` at ``t1``, lagcodegen's CVODE from ``y`` at ``t0``."""
    cm = build_code(code if code is not None else generate_code(scene, "c"))
    res = cm.simulate([t0, t1], y0=list(y), params=dict(zip(cm.param_names, p)), rtol=REFERENCE_RTOL,
                      atol=REFERENCE_ATOL)
    names = ["t", *cm.state_names, *cm.output_names]
    return names, [float(res.t[-1]), *map(float, res.y[-1]), *(float(res[o][-1]) for o in cm.output_names)]


def _constrained_bundle_reference(system: ConstrainedSystem, options: dict, y: Sequence[float], p: Sequence[float],
                                  t0: float, t1: float) -> tuple[list[str], list[float]]:
    """The reference row of a constrained bundle's ``make check``: t, (q, q') and the outputs at
    ``t1`` of the index-1 formulation compiled with the bundle's ``options``, from ``y`` at
    ``t0`` projected onto the constraints, as the bundle's RK4 example starts."""
    opts = dict(options)
    columns = opts.pop("columns")
    sim = compile_constrained(system, "index1", **opts)
    n = sim.n
    res = sim.simulate([t0, t1], q0=list(y[:n]), v0=list(y[n:]), params=dict(zip(sim.param_names, p)),
                       rtol=REFERENCE_RTOL, atol=REFERENCE_ATOL, initial="project", events=False)
    names = ["t", *sim.state_names[:2 * n], *columns]
    return names, [float(res.t[-1]), *map(float, res.y[-1][:2 * n]), *(float(res[o][-1]) for o in columns)]


register_reference_run("scene", _bundle_reference)
register_reference_run("constrained", _constrained_bundle_reference)
