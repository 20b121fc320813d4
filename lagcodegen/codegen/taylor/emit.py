"""C text of the Taylor integrator of a scene: the jet (one straight-line body over the
elementary operations inside a C loop over the orders; for a small model, its first orders
written out before the loop by :mod:`.unroll`), the step-size rule, dense output,
event root finding and the driver ``<prefix>_taylor_solve``, rendered from the jinja2
templates in ``templates/taylor``.

Two sets of files (the jet from the same template, taylor/jet.c.j2):

* :func:`taylor_sources`: ``<prefix>_taylor.h`` and ``<prefix>_taylor.c``, C99 + libm, standalone
  (what C bundles ship): they compute the equations, the outputs (``<prefix>_taylor_outputs``) and
  the events themselves, the driver (taylor/_driver.j2) compiled with the sizes as constants, its
  step rules and event location printed from the runtime's driver (:func:`driver_section`);
* :func:`jet_sources` (a model's part: its jet and the table ``lcg_taylor_model``) and
  :func:`runtime_sources` (the model-independent driver, real C files of lagcodegen/runtime/:
  ``lcg_taylor.c`` with ``lcg_taylor_driver.h``, the step it shares with the integrator object's
  ``lcg_taylor_stepper.c``; compiled once per installation): what ``simulate(method="taylor")``
  builds.

As :class:`~lagcodegen.codegen.record.GeneratedCode` records (:func:`taylor_code`: the standalone
integrator with the model header, for :func:`lagcodegen.build.build`; :func:`jet_code`: the jet
for the runtime's driver, compiled by :func:`lagcodegen.libraries.taylor_jet_library`).
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass

import symengine as se

# --- the rest of lagcodegen: the one place to repoint when modules move -------------------
from ..c import c_expr, print_block
from ..record import GeneratedCode, header_context, new_code
from ..templates import environment, templates_dir
from ..signatures import (DRIVERS, TAYLOR_EVENTS, TAYLOR_OPTIONS, TAYLOR_STATS, cffi_struct,
                          standalone)
from ..signatures import c_header as types_header
from ...codes import c_header
from ...errors import LagcodegenError
from ...runtime import source as runtime_file
from ...runtime import sources as runtime_files
from ...formulation.kernels import Block, substituter
from ...formulation.scene import Scene
from ...formulation.events import scene_events
from ...model.events import Event
from ...version import __version__
# ------------------------------------------------------------------------------------------
from .decompose import Const, Decomposition, decompose
from .unroll import MAX_TERMS, terms, unrolled_orders

#: Operations per C function of the jet (one function when they all fit): gcc's time on one
#: straight-line function grows faster than its length.
CHUNK = 64

#: Highest Taylor order the generated code supports (the jet's storage is sized at run time
#: for the order used).
P_MAX = 30


@dataclass(frozen=True)
class _EventInfo:
    name: str
    row: int
    direction: int
    terminal: int


def _coef(value) -> str:
    """C text of a coefficient: ``c[k]`` for a run constant, else the exact number."""
    if isinstance(value, Const):
        return f"c[{value.index}]"
    text = c_expr(se.sympify(value))
    if "." not in text and "e" not in text and "/" not in text:
        text += ".0"
    if text.startswith("-"):
        text = f"({text})"
    return text


#: The model argument of the runtime driver's functions (lcg_taylor_driver.h), with what follows it
#: on its line or the next (a standalone integrator has its sizes compiled in: no model argument).
_MODEL_ARGUMENT = re.compile(r"const lcg_taylor_model \*m,\s+")
_MODEL_PASSED = re.compile(r"\b(tl_\w+)\(m, ")
_RUNTIME_ONLY = re.compile(r"^#ifdef LCG_TAYLOR_RUNTIME\n.*?^#endif\n", re.M | re.S)


def driver_section(name: str, *, options_type: str, jet_name: str = "lcg_taylor_jet", indent: int = 0) -> str:
    """The part ``name`` of the runtime's Taylor driver (lagcodegen/runtime/lcg_taylor_driver.h,
    between the lines "shared with <prefix>_taylor.c: NAME" and "end of NAME") as a standalone
    integrator prints it (templates/taylor/_driver.j2): without the model argument ``m`` and the
    runtime-only lines (``#ifdef LCG_TAYLOR_RUNTIME`` ... ``#endif``), with its own options type and
    jet function name, each line indented by ``indent`` more spaces. The step rules are written once."""
    text = runtime_file("lcg_taylor_driver.h")
    begin = re.search(rf"^[ ]*/\* shared with <prefix>_taylor\.c: {re.escape(name)} \*/\n", text, re.M)
    end = re.search(rf"^[ ]*/\* end of {re.escape(name)} \*/\n", text, re.M)
    if begin is None or end is None or end.start() < begin.end():
        raise LagcodegenError(f"lcg_taylor_driver.h has no part {name!r} shared with the standalone integrator")
    part = _RUNTIME_ONLY.sub("", text[begin.end():end.start()])
    part = _MODEL_PASSED.sub(r"\1(", _MODEL_ARGUMENT.sub("", part))
    part = part.replace("lcg_taylor_options", options_type).replace("lcg_taylor_jet(", f"{jet_name}(")
    pad = " " * indent
    return "".join(pad + line if line.strip() else line for line in part.splitlines(keepends=True))


def _jinja():
    env = environment()
    env.tests["row"] = lambda e: isinstance(e, int) and not isinstance(e, bool)
    env.tests["zero"] = lambda e: not isinstance(e, (int, Const)) and e == 0
    env.globals["coef"] = _coef
    env.globals["runtime_source"] = runtime_file  # event location (lcg_taylor_roots.h), printed as it is
    env.globals["driver_section"] = driver_section  # the runtime driver's step rules, for standalone integrators
    return env


def taylor_context(scene: Scene, d: Decomposition, events=()) -> dict:
    """The template context of ``taylor.h.j2``/``taylor.c.j2``."""
    n = d.n
    conv = [(i, d.M[i][j], j) for i in range(n) for j in range(n) if isinstance(d.M[i][j], int)]
    conv_rows = [(i, [(m, j) for i2, m, j in conv if i2 == i]) for i in range(n) if any(c[0] == i for c in conv)]
    const_lines = [f"c[{k}] = {c_expr(e)};" for k, e in enumerate(d.consts)]
    kinds = {op.kind for op in d.ops}
    c = substituter(scene)
    outs = scene.output_list()
    ctx = header_context(scene, new_code(scene))
    ctx.update(
        n=n, nz=d.nz, ny=d.ny, nout=len(outs), kin=d.kin, ne=len(events), nrows=d.nrows, p_max=P_MAX,
        outputs_block=print_block(Block([("out", k) for k in range(len(outs))], [c(o.expr) for o in outs])),
        ops=d.ops, chunks=[d.ops[k:k + CHUNK] for k in range(0, len(d.ops), CHUNK)] or [[]], chunk_size=CHUNK,
        kinds=kinds, labels=d.labels, consts=d.consts, const_lines=const_lines, form=d.form,
        M=d.M, F=d.F, rates=d.rates, conv=conv, conv_rows=conv_rows, time_row=d.time_row,
        mass_constant=d.constant_mass, mass_diagonal=d.diagonal_mass,
        table=False, outputs_name=f"{scene.prefix}_taylor_outputs",
        unrolled=unrolled_orders(d, _coef) if len(d.ops) <= CHUNK and terms(d) <= MAX_TERMS else None,  # small jets
        events=[_EventInfo(ev.name, row, int(ev.direction), int(bool(ev.terminal)))
                for row, ev in zip(d.events, events)])
    return ctx


def check_events(scene: Scene, events=()) -> list[Event]:
    """``events`` as :class:`Event` s whose expressions use only the model's symbols
    (coordinates, velocities, parameters, t) and the names of its outputs:
    :func:`lagcodegen.formulation.events.scene_events`, as on CVODE."""
    return scene_events(scene, events)


def taylor_sources(scene: Scene, events=(), decomposition: Decomposition | None = None, *,
                   example: bool = False, q0: float = 0.1, t_end: float = 10.0, y0=None,
                   param_values=None) -> dict[str, str]:
    """``{"<prefix>_taylor.h": ..., "<prefix>_taylor.c": ...}`` for ``scene`` with ``events``
    compiled in: standalone C99 + libm. ``example``: also ``taylor_example.c``, a program
    printing a run from q = ``q0`` at rest (or the whole state ``y0``) over [0, ``t_end``], with
    the parameters' defaults (or ``param_values``, in run-time parameter order) (for bundles)."""
    events = check_events(scene, events)
    d = decomposition or decompose(scene, events)
    ctx = taylor_context(scene, d, events)
    env = _jinja()
    files = {f"{scene.prefix}_taylor.h": env.get_template("taylor/taylor.h.j2").render(**ctx),
             f"{scene.prefix}_taylor.c": env.get_template("taylor/taylor.c.j2").render(**ctx)}
    if example:
        y0 = ([repr(float(v)) for v in y0] if y0 is not None
              else [repr(float(q0))] * d.n + ["0.0"] * (d.n + d.nz))
        files["taylor_example.c"] = env.get_template("taylor/example.c.j2").render(
            **ctx, y0=y0, q0=q0, t_end=repr(float(t_end)),
            param_defaults=[repr(float(v)) for v in (param_values if param_values is not None
                                                      else scene.default_parameters())])
    return files


#: The model-independent Taylor driver: real C files of lagcodegen/runtime/ (compiled once per
#: installation into the Taylor runtime, :func:`lagcodegen.solvers.taylor.runner.taylor_runtime`).
RUNTIME_FILES = ("lcg_taylor.c", "lcg_taylor.h", "lcg_taylor_adapter.h", "lcg_taylor_driver.h", "lcg_taylor_roots.h",
                 "lcg_control.h", "lcg_pool.h")
#: The templates of what the runtime renders: the table of a model's jet (shipped with every jet too).
RUNTIME_TEMPLATES = {"lcg_taylor_model.h": "taylor/lcg_taylor_model.h.j2"}
#: Every template file the Taylor runtime's rendered sources come from (with those they include).
RUNTIME_TEMPLATE_FILES = ("taylor/lcg_taylor_model.h.j2",)


def runtime_key_texts() -> list[str]:
    """What the Taylor runtime's sources are made of, for its cache key (without rendering them):
    the runtime's files, the templates of its rendered parts and the result codes."""
    folder = templates_dir()
    texts = [f"{name}\0{(folder / name).read_text()}" for name in sorted(RUNTIME_TEMPLATE_FILES)]
    return texts + [f"{name}\0{text}" for name, text in sorted(runtime_files(RUNTIME_FILES).items())] + [
        c_header(), types_header(DRIVERS["taylor"], __version__)]


def runtime_sources() -> dict[str, str]:
    """The model-independent Taylor driver ``lcg_taylor.[ch]`` (with the driver's body
    ``lcg_taylor_driver.h``, the run control and pool it includes, and the generated ``lcg_codes.h``
    and ``lcg_taylor_types.h``) and the table of a model's jet it takes, ``lcg_taylor_model.h``."""
    env = _jinja()
    ctx = dict(version=__version__, p_max=P_MAX)
    types = DRIVERS["taylor"]
    return {**runtime_files(RUNTIME_FILES), "lcg_codes.h": c_header(),
            types.header_name: types_header(types, __version__),
            **{name: env.get_template(t).render(**ctx) for name, t in RUNTIME_TEMPLATES.items()}}


def jet_sources(scene: Scene, events=(), decomposition: Decomposition | None = None) -> dict[str, str]:
    """``<prefix>_taylor_jet.c`` (the model part of the Taylor integrator: jet, outputs, event rows
    and their table ``<prefix>_taylor_model``, libm only) and ``lcg_taylor_model.h``."""
    events = check_events(scene, events)
    d = decomposition or decompose(scene, events)
    ctx = taylor_context(scene, d, events)
    ctx.update(table=True, outputs_name="tl_outputs")
    env = _jinja()
    return {"lcg_taylor_model.h": env.get_template("taylor/lcg_taylor_model.h.j2").render(version=__version__,
                                                                                         p_max=P_MAX),
            f"{scene.prefix}_taylor_jet.c": env.get_template("taylor/jet_table.c.j2").render(**ctx)}


def taylor_cdef(prefix: str) -> str:
    """cffi declarations of a model's own Taylor driver (<prefix>_taylor.h): its structs from the
    runtime driver's declaration (:func:`lagcodegen.codegen.signatures.standalone`; every field,
    so that cffi checks the header's layout), its functions."""
    p = prefix
    structs = "\n".join(cffi_struct(standalone(s, p)) for s in (TAYLOR_OPTIONS, TAYLOR_STATS, TAYLOR_EVENTS))
    return "\n" + structs + f"""
int {p}_taylor_solve(const double *p, const double *y0, int nt, const double *tout, double *yout,
                     double *out, const {p}_taylor_options *opt, {p}_taylor_stats *st,
                     {p}_taylor_events *ev);
int {p}_taylor_jet(double t, const double *y, const double *p, int order, double *jet);
int {p}_taylor_outputs(double t, const double *y, const double *p, double *out);
"""


def taylor_code(scene: Scene, events=()) -> tuple[GeneratedCode, Decomposition, list]:
    """The Taylor files of ``scene`` as a :class:`GeneratedCode` ready for
    :func:`lagcodegen.build.build` (``native=False``: no SUNDIALS): ``<prefix>_taylor.h``/``.c``
    plus the model header ``<prefix>.h`` and a small ``<prefix>_taylor_model.c`` defining its
    functions through the Taylor code (no model compiled twice: the n = 20 pendulum builds in
    about the time of its plain model)."""
    events = check_events(scene, events)
    d = decompose(scene, events)
    plain = dataclasses.replace(scene, jacobian=False, sparse_jacobian=False)
    code = new_code(plain)
    code.scene = scene
    ctx = header_context(plain, code)
    env = environment()
    code.files[code.header_name] = env.get_template("c/model.h.j2").render(**ctx)
    code.files.update(taylor_sources(scene, events, d))
    code.files[f"{scene.prefix}_taylor_model.c"] = env.get_template("taylor/model_shim.c.j2").render(**ctx)
    code.cdef_extra += taylor_cdef(scene.prefix)
    code.cffi_headers.append(f"{scene.prefix}_taylor.h")
    return code, d, events


def jet_code(scene: Scene, events=()) -> tuple[GeneratedCode, Decomposition, list]:
    """The model part of the Taylor integrator of ``scene`` for the runtime's driver: a
    :class:`GeneratedCode` (layout and names of the plain scene) whose files are
    ``<prefix>_taylor_jet.c`` and ``lcg_taylor_model.h``."""
    events = check_events(scene, events)
    d = decompose(scene, events)
    code = new_code(dataclasses.replace(scene, jacobian=False, sparse_jacobian=False))
    code.scene = scene
    code.files.update(jet_sources(scene, events, d))
    return code, d, events
