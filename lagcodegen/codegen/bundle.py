"""Embeddable bundles: the generated model code plus build files, examples and a README.

:func:`write_bundle` writes, into one folder, everything a C or Fortran project needs to use
a :class:`~lagcodegen.formulation.scene.Scene` without lagcodegen:

* the model: ``<prefix>.h`` and ``<prefix>.c`` (C99) or ``<prefix>.f90`` (Fortran 2008
  module ``<prefix>_mod`` with C bindings, see :mod:`lagcodegen.codegen.fortran`);
* ``Makefile``: the static library ``lib<prefix>.a``, ``make rk4``, ``make check`` (runs the
  RK4 example), ``make cvode`` (the SUNDIALS example, on request);
* ``CMakeLists.txt``: the same library and RK4 example; the SUNDIALS example only if
  ``find_package(SUNDIALS CONFIG)`` succeeds (linking ``SUNDIALS::cvode``);
* ``rk4_example.c``: a fixed-step RK4 integration that needs nothing but a C compiler;
* ``cvode_example.c`` (``sundials_example=True``): the same with SUNDIALS CVODE;
* ``README.md``: how to call each function, array layouts, return codes;
* with ``sensitivities=True`` (C): ``<prefix>_sens.c``, the forward sensitivity functions
  ``<prefix>_sens_rhs`` and ``<prefix>_sens_outputs`` (:mod:`lagcodegen.codegen.sensitivity`),
  compiled into the library, their prototypes in ``<prefix>.h``, and ``sens_example.c``, an RK4
  integration of the state with its sensitivities to every run-time parameter and initial value.

Constrained systems (:class:`~lagcodegen.theory.constraints.ConstrainedSystem`, index-1 formulation):
:func:`render_constrained_bundle`, or :func:`write_bundle` given the system instead of a scene,
bundles ``<prefix>_dae.h`` with ``<prefix>_dae.c`` or ``<prefix>_dae.f90`` (augmented-system
solve, index-1 right-hand side, residuals, projection, outputs; optionally events and the GGL
residual), the same Makefile and CMakeLists.txt, an RK4 example of the index-1 ODE (initial
state projected onto the constraints; Baumgarte parameters and per-step projection as options)
and a README describing the constrained functions. No SUNDIALS example.

Everything is rendered in memory first; then each file whose content changed is replaced
atomically, and unchanged files are not touched (their modification times stay, so ``make``
rebuilds nothing). The output depends on the scene and the options only (no timestamps,
fixed order): regenerating gives the same bytes.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

from ..codes import c_header as codes_header
from ..derivation import require_lagrange
from ..errors import LagcodegenError, ModelError
from ..formulation.scene import Scene
from ..model.outputs import DEFAULT_CONSTRAINED_OUTPUTS
from ..theory.constraints import ConstrainedSystem
from ..util import BAUMGARTE_AUTO, atomic_write, check_baumgarte, check_finite, folder_problem, read_regular_file
from ..version import __version__
from .bundle_contacts import (check_contact_bundle, contact_columns, contact_context, contact_files, contact_table,
                              library_sources)
from .constrained import generate_constrained
from .languages import LANGUAGES, backend, generate_code
from .record import GeneratedCode
from .sensitivity import SENS_OUTPUTS, SENS_RHS, sensitivity_source
from .signatures import DRIVERS, c_header as types_header
from .templates import environment

#: The CVODE example's methods: name -> (CVODE constant, text).
CVODE_METHODS = {"bdf": ("CV_BDF", "BDF"), "adams": ("CV_ADAMS", "Adams")}
#: Standalone integrators a C bundle carries besides the model code, registered by their code
#: generator (:mod:`lagcodegen.codegen.taylor` registers "taylor"): name -> function(scene, y0,
#: parameter values, t_end) -> {file name: text} with the sources and ``<name>_example.c`` (a
#: program that needs only a C compiler), raising ModelError when the scene cannot have one.
INTEGRATORS: dict = {}


def register_integrator(name: str, sources) -> None:
    """Make C bundles carry the integrator ``name`` (see :data:`INTEGRATORS`)."""
    INTEGRATORS[name] = sources
#: Default initial coordinates of the examples when none are given (velocities and z: 0).
DEFAULT_Q0 = 0.5
#: ``make check``: the RK4 example's run compared with ``reference.csv`` (lagcodegen's own CVODE
#: integration at the tolerances below, written when the bundle is rendered) spans at most
#: CHECK_SPAN time units from t_start; each value v of its final row must be within
#: CHECK_TOL (1 + |r|) of its reference r.
CHECK_SPAN = 1.0
CHECK_TOL = 1e-6
REFERENCE_RTOL, REFERENCE_ATOL = 1e-12, 1e-14


def _c_double(value: float) -> str:
    """A C double literal that reads back as exactly ``value``."""
    text = repr(float(value))
    return text if "." in text or "e" in text else text + ".0"


def _initial_state(code: GeneratedCode, y0) -> list[float]:
    if y0 is None:  # quaternions' scalar parts 1 (the code's neutral configuration)
        neutral = getattr(code, "q_neutral", None) or [0.0] * code.n
        return [1.0 if x == 1.0 else DEFAULT_Q0 for x in neutral] + [0.0] * (code.speeds + code.nz)
    values = [check_finite(v, "bundle initial state") for v in y0]
    if len(values) == code.n + code.speeds:
        values += [0.0] * code.nz
    if len(values) != code.ny:
        raise ModelError(f"bundle initial state: expected {code.ny} values ({', '.join(code.state_names)}), "
                         f"got {len(values)}")
    return values


def _parameters(code: GeneratedCode, params: Mapping[str, float] | None) -> list[float]:
    values = dict(zip(code.param_names, code.param_defaults))
    for name, value in (params or {}).items():
        if name not in values:
            raise ModelError(f"bundle: {name!r} is not a run-time parameter of this scene "
                             f"(run-time parameters: {', '.join(values) or 'none'})")
        values[name] = check_finite(value, f"bundle parameter {name!r}")
    return [values[name] for name in code.param_names]


def render_bundle(scene: Scene, lang: str = "c", sundials_example: bool = True, *,
                  y0: Sequence[float] | None = None, params: Mapping[str, float] | None = None,
                  t_start: float = 0.0, t_end: float = 10.0, steps: int | None = None,
                  code: GeneratedCode | None = None, method: str = "bdf",
                  sensitivities: bool = False, reference: bool = True) -> dict[str, str]:
    """The files of the bundle of ``scene`` (name -> text), rendered in memory (with
    ``sensitivities``, models with generalized speeds are refused by name).

    ``y0`` (the whole state, or q and q' with z = 0), ``params`` (run-time parameter values by
    name), ``t_start``, ``t_end`` and ``steps`` are the examples' defaults (the examples take
    others on their command line): by default q = 0.5, q' = 0, the parameters' defaults, t
    from 0 to 10 and RK4 steps of at most 1e-3. ``code``: the model code, if already generated
    for this scene and language. ``method``: the linear multistep method of the CVODE example,
    "bdf" or "adams" (the model code is the same for both). ``sensitivities``: also the forward
    sensitivity functions (C bundles; module docstring).

    ``reference``: compile the scene and integrate it with lagcodegen's CVODE (rtol
    :data:`REFERENCE_RTOL`, atol :data:`REFERENCE_ATOL`) from the examples' defaults over at
    most :data:`CHECK_SPAN`, and write the final values as ``reference.csv``: ``make check``
    runs the RK4 example over that span and fails unless each value is within
    :data:`CHECK_TOL` (1 + |reference|). Where the model cannot be compiled or run here (no C
    compiler, the run fails), the bundle has no reference and ``make check`` says so.
    """
    if sensitivities:
        require_lagrange(scene.eom, "a bundle with sensitivities")
    if isinstance(scene, ConstrainedSystem):
        raise ModelError("render_bundle takes a Scene; bundle a ConstrainedSystem with render_constrained_bundle "
                         "or write_bundle")
    if code is None:
        code = generate_code(scene, lang)
    elif lang not in LANGUAGES:
        raise ModelError(f"unknown language {lang!r} (choose from {', '.join(LANGUAGES)})")
    if method not in CVODE_METHODS:
        raise ModelError(f"bundle: unknown CVODE method {method!r} (choose from {', '.join(CVODE_METHODS)})")
    be = backend(lang)
    t_start, t_end, steps = _checked_span(t_start, t_end, steps)
    source = f"{code.prefix}{be.suffix}"
    names = [code.header_name, source]
    missing = [name for name in names if name not in code.files]
    if missing:
        raise ModelError(f"bundle: the generated code has no {', '.join(missing)} (language {lang!r}?)")

    folded = sorted(scene.folded.items())
    table = [(code.header_name, "C header: sizes, array layouts, return codes, function prototypes"),
             (source, be.source_description(code.prefix)),
             ("Makefile", f"`make`: lib{code.prefix}.a and rk4_example; `make check` runs it"),
             ("CMakeLists.txt", "the same with CMake"),
             ("rk4_example.c", "fixed-step RK4 integration, CSV on stdout; needs only a C compiler")]
    if sundials_example:
        table.append(("cvode_example.c", "the same with SUNDIALS CVODE (built by CMake when SUNDIALS is found)"))
    inputs = [(name, code.param_names.index(name)) for name in code.input_names] if be.c_sources else []
    if inputs:
        table += [("lcg_inputs.h", "input tables: a piecewise cubic per input, setting its slot of p (C99 + libm)"),
                  ("lcg_inputs.c", "their functions"),
                  ("lcg_inputs_types.h", "their structs (with lcg_model.h, lcg_codes.h)"),
                  ("inputs_example.c", "RK4 with the inputs read from tables (`make inputs_example`)")]
    if sensitivities:
        if not be.c_sources:
            raise ModelError(f"bundle: the sensitivity functions are C (sensitivities=True needs lang='c', "
                             f"not {lang!r})")
        table += [(f"{code.prefix}_sens.c", "forward sensitivities: the state's and its sensitivities' right-hand "
                                            "side, the outputs' sensitivities (C99 + libm; in the library)"),
                  ("sens_example.c", "RK4 of the state and its sensitivities to every parameter and initial "
                                     "value, CSV on stdout")]
    table.append(("README.md", "this file"))
    y_values = _initial_state(code, y0)
    ctx = dict(
        version=__version__, prefix=code.prefix, PREFIX=code.prefix.upper(), model_name=code.model_name,
        lang=lang, backend=be, lang_name=be.title,
        header=code.header_name, source=source, stem=code.prefix, n=code.n, nz=code.nz, ny=code.ny, np=code.np,
        nout=code.nout, state_names=code.state_names, param_names=code.param_names,
        param_values=[_c_double(v) for v in _parameters(code, params)], output_names=code.output_names,
        jacobian=code.jacobian, folded=folded,
        folded_text=", ".join(f"`{name}` = {_c_double(value)}" for name, value in folded),
        y0=[_c_double(v) for v in y_values], t_start=_c_double(t_start), t_end=_c_double(t_end),
        steps=steps, every=max(1, steps // 100), sundials_example=sundials_example, file_table=table,
        cvode_method=CVODE_METHODS[method][0], cvode_method_name=CVODE_METHODS[method][1], inputs=inputs,
        sens=bool(sensitivities))
    if inputs:
        ctx.update(input_names=[name for name, _ in inputs], input_slots=[s for _, s in inputs],
                   max_h=_c_double((t_end - t_start) / steps))
    integrators, skipped, extra = [], [], {}
    for name, sources in (INTEGRATORS.items() if be.c_sources else ()):
        try:
            produced = sources(scene, y_values, _parameters(code, params), t_end)
        except ModelError as exc:
            skipped.append((name, str(exc)))
            continue
        extra.update(produced)
        integrators.append(dict(name=name, sources=sorted(k for k in produced if k.endswith(".c")
                                                           and not k.endswith("_example.c")),
                                header=next(k for k in produced if k.endswith(".h")), example=f"{name}_example"))
        table.insert(-1, (next(k for k in produced if k.endswith(".c") and not k.endswith("_example.c")),
                          f"the {name} integrator, standalone (C99 + libm, no model code needed)"))
        table.insert(-1, (f"{name}_example.c", f"a {name} integration, a table on stdout; needs only a C compiler"))
    ctx.update(integrators=integrators, skipped_integrators=skipped)
    ref_text, ctx["check"] = None, None
    if reference:
        ref_text, ctx["check"] = reference_values("scene", code.model_name, (scene, code if be.c_sources else None),
                                                  y_values, _parameters(code, params), t_start, t_end, steps)
        if ref_text is not None:
            table.insert(-1, ("reference.csv", "the final row `make check` expects of rk4_example (lagcodegen's "
                                               "CVODE at tight tolerances)"))
    env = environment()
    files = {name: code.files[name] for name in names}
    files.update(extra)
    if ref_text is not None:
        files["reference.csv"] = ref_text
    files["Makefile"] = env.get_template("bundle/Makefile.j2").render(**ctx)
    files["CMakeLists.txt"] = env.get_template("bundle/CMakeLists.txt.j2").render(**ctx)
    files["rk4_example.c"] = env.get_template("bundle/rk4_example.c.j2").render(**ctx)
    if sundials_example:
        files["cvode_example.c"] = env.get_template("bundle/cvode_example.c.j2").render(**ctx)
    if inputs:
        files.update(inputs_files())
        files["inputs_example.c"] = env.get_template("bundle/inputs_example.c.j2").render(**ctx)
    if sensitivities:
        files.update(sensitivity_files(scene, code, env, ctx))
    files["README.md"] = env.get_template("bundle/README.md.j2").render(**ctx)
    return files


def register_reference_run(kind: str, run) -> None:
    """Give bundles of ``kind`` their reference run (:data:`REFERENCE_RUNS`). "scene":
    ``run(scene, code, y, p, t0, t1)`` (``code``: the scene's C code, or None); "constrained":
    ``run(system, options, y, p, t0, t1)`` (``options``: those of the bundle's index-1 code,
    ``outputs``, ``events``, ``runtime_parameters``, ``values``, ``prefix``, ``baumgarte``, and
    ``columns``, the names of the outputs the example prints). Each returns
    (column names, values): t, the state and the outputs at t1, integrated from the state y at
    t0 with the run-time parameter values p. :mod:`lagcodegen.api` registers lagcodegen's own
    CVODE runs (this stage compiles nothing itself)."""
    REFERENCE_RUNS[kind] = run


#: The runs that write ``reference.csv``, by kind of bundle (:func:`register_reference_run`);
#: a kind without one: bundles without a reference.
REFERENCE_RUNS: dict = {}


def reference_values(kind: str, model_name: str, subject, y_values: list[float], p_values: list[float],
                     t_start: float, t_end: float, steps: int) -> tuple[str | None, dict]:
    """(the text of ``reference.csv`` or None, the Makefile's check settings): t, the state and
    the outputs at t_start + min(:data:`CHECK_SPAN`, t_end - t_start) from ``y_values`` with the
    run-time parameters ``p_values``, by the run of ``kind`` (:data:`REFERENCE_RUNS`) given
    ``subject`` (its first two arguments). The check's RK4 run takes steps no longer than the
    example's. Without a reference, the settings say why (``reason``)."""
    t_check = t_start + min(CHECK_SPAN, t_end - t_start)
    n_check = max(100, math.ceil(steps * (t_check - t_start) / (t_end - t_start)))
    settings = dict(t_end=_c_double(t_check), steps=n_check, tol=f"{CHECK_TOL:g}", reason="")
    run = REFERENCE_RUNS.get(kind)
    if run is None:
        settings["reason"] = "no reference run was registered when the bundle was written"
        return None, settings
    try:
        names, values = run(*subject, list(y_values), list(p_values), t_start, t_check)
    except (LagcodegenError, OSError) as exc:
        # one line of plain words: it goes into a Makefile's echo and the README
        said = " ".join(str(exc).split()).translate({ord(c): "'" for c in "\"`"}).replace("\\", "/").replace("$", "")
        settings["reason"] = (f"lagcodegen could not run the model when it wrote the bundle: "
                              f"{said[:300]}{' ...' if len(said) > 300 else ''}")
        return None, settings
    if not all(map(math.isfinite, values)):
        settings["reason"] = "the reference run gave non-finite values"
        return None, settings
    text = (f"# reference.csv -- generated by lagcodegen {__version__} for model \"{model_name}\": the final row "
            f"that\n# `make check` expects of ./rk4_example -t {settings['t_end']} -n {n_check} (lagcodegen's CVODE, "
            f"rtol {REFERENCE_RTOL:g},\n# atol {REFERENCE_ATOL:g}, from the examples' default initial state and "
            f"parameters): each value\n# within {CHECK_TOL:g} (1 + |reference|).\n"
            + ",".join(names) + "\n" + ",".join(f"{float(v):.12g}" for v in values) + "\n")
    return text, settings


def sensitivity_files(scene: Scene, code: GeneratedCode, env, ctx: dict) -> dict[str, str]:
    """The sensitivity part of a C bundle: ``<prefix>_sens.c``, the model header with their
    prototypes added (before its closing C++ guard), ``sens_example.c``; ``ctx`` gets the
    example's directions (every run-time parameter, then every initial value)."""
    prefix = code.prefix
    sources = sensitivity_source(scene, prefix)
    header = code.files[code.header_name]
    guard = "#ifdef __cplusplus\n}"
    at = header.rfind(guard)
    if at < 0:
        raise ModelError(f"bundle: the header {code.header_name} has no closing C++ guard to add the sensitivity "
                         "prototypes before")
    PREFIX = prefix.upper()
    block = (f"/* Forward sensitivities ({prefix}_sens.c): ydot[NY] = f(t, y, p) and sdot[j*NY + i] = d ydot[i] / "
             f"d theta_j\n * for ns directions with s[j*NY + i] = d y[i] / d theta_j: which[j] = k for the "
             f"run-time\n * parameter p[k], -1 for an initial value. Returns {PREFIX}_OK, "
             f"{PREFIX}_ERR_SINGULAR_MASS or\n * {PREFIX}_ERR_NONFINITE. */\n{SENS_RHS.format(prefix=prefix)};\n\n"
             f"/* dout[j*NOUT + k] = d out[k] / d theta_j at (t, y, s) (NOUT = {code.nout}).\n * Returns {PREFIX}_OK "
             f"or {PREFIX}_ERR_NONFINITE. */\n{SENS_OUTPUTS.format(prefix=prefix)};\n\n")
    directions = list(code.param_names) + [f"{name}(0)" for name in code.state_names]
    ctx.update(ns=len(directions), sens_directions=directions,
               sens_which=list(range(code.np)) + [-1] * code.ny,
               sens_rhs=SENS_RHS.format(prefix=prefix), sens_outputs=SENS_OUTPUTS.format(prefix=prefix))
    return {**sources, code.header_name: header[:at] + block + header[at:],
            "sens_example.c": env.get_template("bundle/sens_example.c.j2").render(**ctx)}


def inputs_files() -> dict[str, str]:
    """The runtime's input tables as a bundle ships them: ``lcg_inputs.h``/``.c`` as they are,
    their structs ``lcg_inputs_types.h`` and what that includes (``lcg_model.h``, ``lcg_codes.h``)."""
    from .. import runtime
    return {**runtime.sources(("lcg_inputs.h", "lcg_inputs.c", "lcg_model.h")), "lcg_codes.h": codes_header(),
            "lcg_inputs_types.h": types_header(DRIVERS["inputs"], __version__)}


def _checked_span(t_start, t_end, steps) -> tuple[float, float, int]:
    t_start = check_finite(t_start, "bundle t_start")
    t_end = check_finite(t_end, "bundle t_end")
    if not t_end > t_start:
        raise ModelError(f"bundle: t_end ({t_end:g}) must be greater than t_start ({t_start:g})")
    if steps is None:
        steps = max(1000, math.ceil(1000 * (t_end - t_start)))
    if int(steps) != steps or steps < 1:
        raise ModelError(f"bundle: steps must be a positive integer, got {steps!r}")
    return t_start, t_end, int(steps)


@dataclass(frozen=True)
class ExampleRun:
    """The defaults of a bundle's example programs (they take others on their command line): the
    initial state ``y0``, the run-time parameter values ``params`` by name, the span ``t_start``
    to ``t_end`` and the RK4 ``steps`` (None: steps of at most 1e-3)."""

    y0: Sequence[float] | None = None
    params: Mapping[str, float] | None = None
    t_start: float = 0.0
    t_end: float = 10.0
    steps: int | None = None

    @classmethod
    def of(cls, example: "ExampleRun | None", fields: dict, caller: str) -> "ExampleRun":
        """``example``, or one made of the keywords ``fields`` (its field names; TypeError naming
        another, or both given)."""
        unknown = sorted(set(fields) - set(cls.__dataclass_fields__))
        if unknown:
            raise TypeError(f"{caller}() got an unexpected keyword argument {unknown[0]!r}")
        if example is None:
            return cls(**fields)
        if fields:
            raise TypeError(f"{caller}(): give the example's values as example=ExampleRun(...) or as keywords "
                            f"({', '.join(sorted(fields))}), not both")
        if not isinstance(example, cls):
            raise TypeError(f"{caller}(): example must be an ExampleRun, got {type(example).__name__}")
        return example


def render_constrained_bundle(system, lang: str = "c", *, outputs: Sequence[str] | None = None,
                              events=(), runtime_parameters=None, values: Mapping[str, float] | None = None,
                              prefix: str | None = None, ggl: bool = False,
                              baumgarte: tuple[float, float] | str = "auto", example: ExampleRun | None = None,
                              reference: bool = True, **example_fields) -> dict[str, str]:
    """The files of the bundle of a :class:`~lagcodegen.theory.constraints.ConstrainedSystem` in the
    index-1 formulation (name -> text), rendered in memory.

    The library is ``<prefix>_dae.h`` with ``<prefix>_dae.c`` (C99) or ``<prefix>_dae.f90``
    (Fortran 2008 module ``<prefix>_dae_mod``, functions bound to the C names): the augmented
    system solve ``<prefix>_kkt``, the index-1 right-hand side ``<prefix>_crhs``, residuals,
    projection, outputs, root functions for ``events``, and with ``ggl`` the GGL residual and
    its Jacobian. The Makefile, CMakeLists.txt and README.md are those of :func:`render_bundle`;
    ``rk4_example.c`` integrates the index-1 ODE with fixed-step RK4 (initial state projected
    onto the constraints; Baumgarte parameters ``baumgarte`` = (alpha, beta) by default, or with
    ``"auto"`` alpha = beta = ``<prefix>_natural_rate`` at the initial state; others and per-step
    projection on its command line). There is no SUNDIALS example (the native
    drivers of :func:`lagcodegen.build.runtime` are written against lagcodegen's own SUNDIALS declarations).
    Systems with contacts (in C) add their contact functions and an example with impacts, and with
    Coulomb friction the runtime's friction core: :mod:`lagcodegen.codegen.bundle_contacts`.

    ``outputs``, ``events``, ``runtime_parameters``, ``values``, ``prefix``: as for
    :func:`lagcodegen.compile_constrained` (default outputs: energy, lambda, residuals);
    ``example`` (an :class:`ExampleRun`), or its fields as keywords: ``y0`` (q and q',
    projected onto the constraints by the example; default q = 0.5, q' = 0), ``params``,
    ``t_start``, ``t_end``, ``steps``: the example's defaults, as for :func:`render_bundle`. ``reference``: ``reference.csv`` and ``make check``'s comparison, as
    for :func:`render_bundle` (the reference run: lagcodegen's index-1 CVODE integration from
    the initial state projected onto the constraints).
    """
    if not isinstance(system, ConstrainedSystem):
        raise ModelError(f"render_constrained_bundle needs a ConstrainedSystem, got {type(system).__name__}")
    if lang not in LANGUAGES:
        raise ModelError(f"unknown language {lang!r} (choose from {', '.join(LANGUAGES)})")
    contacts = bool(system.contacts)  # contacts: bundle_contacts adds their functions and example
    if contacts:
        check_contact_bundle(system, backend(lang).c_sources, ggl)
    run = ExampleRun.of(example, example_fields, "render_constrained_bundle")
    y0, params = run.y0, run.params
    stab = check_baumgarte(baumgarte, "bundle baumgarte")
    auto = stab == BAUMGARTE_AUTO
    alpha, beta = (-1.0, -1.0) if auto else stab  # negative: the example's "auto"
    t_start, t_end, steps = _checked_span(run.t_start, run.t_end, run.steps)
    code, info = generate_constrained(system, ggl=ggl, outputs=DEFAULT_CONSTRAINED_OUTPUTS if outputs is None else outputs,
                                        events=events, runtime_parameters=runtime_parameters, values=values,
                                        prefix=prefix, lang=lang)
    be = backend(lang)
    pre = code.prefix
    header = f"{pre}_dae.h"
    source = f"{pre}_dae{be.suffix}"
    y_values = _initial_state(code, y0)
    folded = sorted(info.folded.items())
    table = [(header, "C header: sizes, array layouts, return codes, function prototypes"),
             (source, be.source_description(f"{pre}_dae")),
             ("Makefile", f"`make`: lib{pre}.a and rk4_example; `make check` runs it"),
             ("CMakeLists.txt", "the same with CMake"),
             ("rk4_example.c", "fixed-step RK4 integration of the index-1 equations, CSV on stdout; "
                               "needs only a C compiler"),
             ("README.md", "this file")]
    check, ref_text = None, None
    if reference:
        options = dict(outputs=DEFAULT_CONSTRAINED_OUTPUTS if outputs is None else list(outputs),
                       columns=contact_columns(system, info.output_names) if contacts else list(info.output_names),
                       events=list(events), runtime_parameters=runtime_parameters,
                       values=values, prefix=prefix, baumgarte=stab)
        ref_text, check = reference_values("constrained", code.model_name, (system, options), y_values,
                                           _parameters(code, params), t_start, t_end, steps)
        if ref_text is not None:
            table.insert(-1, ("reference.csv", "the final row `make check` expects of rk4_example (lagcodegen's "
                                               "CVODE at tight tolerances)"))
    ctx = dict(
        integrators=[], skipped_integrators=[], check=check,
        version=__version__, prefix=pre, PREFIX=pre.upper(), model_name=code.model_name, lang=lang,
        backend=be, lang_name=be.title, header=header, source=source,
        stem=f"{pre}_dae", n=code.n, ny=code.ny, nv=code.speeds, general=system.model.general, nj=info.J, njh=info.JH, ng=info.ng, np=code.np,
        nout=len(info.output_names), nroot=len(info.events), state_names=code.state_names,
        param_names=code.param_names, param_values=[_c_double(v) for v in _parameters(code, params)],
        output_names=info.output_names, roots=[f"{ev.name}: {ev.expr}" for ev in info.events], ggl=ggl,
        ggl_jac=info.ggl_jac, folded=folded,
        folded_text=", ".join(f"`{name}` = {_c_double(value)}" for name, value in folded),
        y0=[_c_double(v) for v in y_values], t_start=_c_double(t_start), t_end=_c_double(t_end),
        alpha=_c_double(alpha), beta=_c_double(beta), auto_stab=auto, steps=steps, every=max(1, steps // 100),
        sundials_example=False, file_table=table, holonomic=[str(f) for f in system.holonomic],
        nonholonomic=[str(r) for r in _nonholonomic_text(system)])
    env = environment()
    files = {header: code.files[header], source: code.files[source]}
    friction = contacts and system.has_friction
    if contacts:
        ctx.update(contact_context(system, info), extra_sources=library_sources(code, friction))
        contact_table(code, table, friction)
        files.update(contact_files(code, friction))
    files["Makefile"] = env.get_template("bundle/Makefile.j2").render(**ctx)
    files["CMakeLists.txt"] = env.get_template("bundle/CMakeLists.txt.j2").render(**ctx)
    example = "rk4_friction.c.j2" if friction else "rk4_impacts.c.j2" if contacts else "rk4_constrained.c.j2"
    files["rk4_example.c"] = env.get_template(f"bundle/{example}").render(**ctx)
    files["README.md"] = env.get_template("bundle/README_constrained.md.j2").render(**ctx)
    if ref_text is not None:
        files["reference.csv"] = ref_text
    return files


def _nonholonomic_text(system) -> list[str]:
    """The nonholonomic rows as text: A . q' + A0 = 0."""
    out = []
    speeds = [v.name for v in system.model.speeds]
    for row in system.rows():
        if row.holonomic:
            continue
        terms = [f"({a})*{v}" for a, v in zip(row.A, speeds) if a != 0]
        if row.A0 != 0:
            terms.append(f"({row.A0})")
        out.append(" + ".join(terms) or "0")
    return out


def stale_files(directory: str | os.PathLike, files: Mapping[str, str]) -> list[str]:
    """Names of ``files`` missing from ``directory`` or with other content there."""
    out = Path(directory)
    stale = []
    for name, text in files.items():
        if read_regular_file(out / name) != text.encode("utf-8"):
            stale.append(name)
    return stale


def write_files(directory: str | os.PathLike, files: Mapping[str, str]) -> list[Path]:
    """Write ``files`` (name -> text) into ``directory``: each changed file atomically, unchanged
    files not at all. Returns the paths written."""
    out = Path(directory)
    problem = folder_problem(out)
    if problem:
        raise LagcodegenError(f"cannot write the files into {out}: {problem}")
    out.mkdir(parents=True, exist_ok=True)
    return [atomic_write(out / name, files[name]) for name in sorted(stale_files(out, files))]


def write_bundle(scene, directory: str | os.PathLike, lang: str = "c", sundials_example: bool | None = None,
                 **options) -> list[Path]:
    """Render the bundle of ``scene`` (see :func:`render_bundle` for ``options``), or of a
    :class:`~lagcodegen.theory.constraints.ConstrainedSystem` in the index-1 formulation (see
    :func:`render_constrained_bundle`), and write it into ``directory``. Returns the paths of
    all bundle files, in name order. ``sundials_example``: default True for a scene; constrained
    bundles have none."""
    if isinstance(scene, ConstrainedSystem):
        if sundials_example:
            raise ModelError("bundles of constrained systems have no SUNDIALS example (sundials_example=True)")
        files = render_constrained_bundle(scene, lang, **options)
    else:
        files = render_bundle(scene, lang, True if sundials_example is None else sundials_example, **options)
    write_files(directory, files)
    return [Path(directory) / name for name in sorted(files)]
