"""The libraries a run asks for beyond a model's own code, generated and compiled by the build
stage on a solver's request: the forward sensitivity functions of a scene
(:func:`sensitivity_library`) and of a constrained system
(:func:`constrained_sensitivity_library`), the event functions (:func:`events_library`) and
their gradients (:func:`events_gradient_library`), the inverse-dynamics regressor
(:func:`regressor_library`); of the Taylor integrator, a model's jet for the Taylor runtime's
driver (:func:`taylor_jet_library`), the jet of a constrained system with contacts
(:func:`taylor_contact_library`), its variational jet along a set of sensitivity directions
(:func:`taylor_variational_library`) and the standalone integrator (:func:`taylor_integrator`, a
cffi module of its own built by :func:`lagcodegen.build.build`).

Each is a :class:`Library`: the open shared library, its path, whether it came from the cache
and the names its C defines. The solvers never generate or compile C themselves: they ask for
the library here (and keep it with the compiled model, :mod:`lagcodegen.solvers.artifacts`);
its sources come from :mod:`lagcodegen.codegen` (the Taylor jets from :mod:`lagcodegen.codegen.taylor`),
its build from :func:`lagcodegen.build.plain_library`, cached by content like every build."""

from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
from pathlib import Path

from .build import DEFAULT_CFLAGS, BuiltModule, build, generated_headers, plain_library
from .codegen.events import events_gradient_function, events_gradient_source, events_function, events_source
from .codegen.record import GeneratedCode, scene_of_code
from .codegen.regressor import regressor_files, regressor_functions
from .codegen.sensitivity import sensitivity_source
from .codegen.sensitivity_constrained import constrained_sensitivity_source
from .codegen.taylor.contacts import contact_jet_code
from .codegen.taylor.decompose import Decomposition
from .codegen.taylor.emit import jet_code, taylor_code
from .codegen.taylor.variational_source import variational_sources
from .runtime import sources as runtime_files


@dataclass(frozen=True)
class Library:
    """A compiled library a run asked for: ``handle`` (ctypes, open while this object lives),
    ``path``, ``cached`` (loaded from the build cache), ``functions`` (what it defines, by role:
    e.g. ``{"events": "<prefix>_events"}``) and ``extra`` (what its generation found beside
    the C, e.g. the regressor's bodies); ``sources`` the C it was compiled from, by file name."""

    handle: ctypes.CDLL
    path: Path
    cached: bool
    functions: dict = field(default_factory=dict)
    extra: tuple = ()
    sources: dict = field(default_factory=dict, repr=False)

    def address(self, role: str) -> int:
        """The address of the function named ``functions[role]``."""
        return ctypes.cast(getattr(self.handle, self.functions[role]), ctypes.c_void_p).value


def _built(label: str, prefix: str, sources: dict, functions: dict, extra: tuple = (), *, cc: str | None = None,
           cflags: tuple[str, ...] = DEFAULT_CFLAGS, verbose: bool = False) -> Library:
    handle, path, cached = plain_library(label, prefix, sources, cc, cflags, verbose=verbose)
    return Library(handle, Path(path), bool(cached), functions, extra, sources)


def sensitivity_library(code: GeneratedCode) -> Library:
    """``<prefix>_sens_rhs`` and ``<prefix>_sens_outputs``: the forward sensitivity functions of
    the scene of ``code`` (:mod:`lagcodegen.codegen.sensitivity`)."""
    scene = scene_of_code(code, "sensitivities")
    prefix = code.prefix
    return _built("sensitivity functions", f"{prefix}_sens", sensitivity_source(scene, prefix),
                  {"rhs": f"{prefix}_sens_rhs", "outputs": f"{prefix}_sens_outputs"})


def constrained_sensitivity_library(system, code: GeneratedCode, output_names) -> Library:
    """``<prefix>_csens_*``: the index-1 sensitivity functions of the constrained ``system``
    compiled as ``code`` (:mod:`lagcodegen.codegen.sensitivity_constrained`)."""
    scene = scene_of_code(code, "sensitivities of a constrained system")
    prefix = scene.prefix
    sources = constrained_sensitivity_source(system, scene, output_names, prefix)
    sources.update(runtime_files(["lcg_model.h"]))
    sources.update(generated_headers())
    roles = ("rhs", "outputs", "project", "model_table", "initial")
    return _built("constrained sensitivity functions", f"{prefix}_csens", sources,
                  {role: f"{prefix}_csens_{role}" for role in roles})


def events_library(code: GeneratedCode, scene, events: list) -> Library:
    """``<prefix>_events``: the checked ``events`` of ``scene`` (:mod:`lagcodegen.codegen.events`)."""
    return _built(f"the event functions of model {code.model_name!r}", f"{code.prefix}_events",
                  events_source(scene, events), {"events": events_function(code.prefix)})


def events_gradient_library(code: GeneratedCode, scene, events: list) -> Library:
    """``<prefix>_events_grad``: dg/dt, dg/dy, dg/dp of the checked ``events`` of ``scene``."""
    return _built(f"the event derivatives of model {code.model_name!r}", f"{code.prefix}_events_grad",
                  events_gradient_source(scene, list(events)), {"gradient": events_gradient_function(code.prefix)})


def regressor_library(code: GeneratedCode) -> Library:
    """``<prefix>_inverse_dynamics_regressor`` and ``<prefix>_regressor_parameters`` of the tree
    scene of ``code`` (:mod:`lagcodegen.codegen.regressor`); ``extra`` the bodies' link names."""
    scene = scene_of_code(code, "inverse_dynamics_regressor")
    sources, bodies = regressor_files(scene, code.prefix, code.model_name)
    fY, fpi = regressor_functions(code.prefix)
    return _built(f"the inverse-dynamics regressor of model {code.model_name!r}", f"{code.prefix}_regressor",
                  sources, {"regressor": fY, "parameters": fpi}, tuple(bodies))


#: A jet of at least this many operations compiles with :data:`LARGE_JET_CFLAGS` where the caller
#: keeps the default flags: gcc -O1 compiled the 12-joint chain's jet (6033 operations) in 3.3 s
#: against 6.1 s at -O2, and its steps ran in 0.95x the time (the 10-link pendulum's, 165
#: operations: 0.99x; the 3-link pendulum's: 1.15x, so small jets stay at -O2).
LARGE_JET_OPS = 2000
LARGE_JET_CFLAGS = ("-O1", "-fPIC", "-std=c99")


def taylor_jet_library(scene, events=(), *, cc: str | None = None, cflags: tuple[str, ...] = DEFAULT_CFLAGS,
                       verbose: bool = False) -> Library:
    """``<prefix>_taylor_table``: the jet of ``scene`` with ``events`` (checked here) for the Taylor
    runtime's driver (:func:`lagcodegen.codegen.taylor.emit.jet_code`), compiled with ``cflags``
    (a large jet with the default flags: :data:`LARGE_JET_CFLAGS`); ``extra`` (the
    :class:`~lagcodegen.codegen.record.GeneratedCode`, its
    :class:`~lagcodegen.codegen.taylor.decompose.Decomposition`, the checked events)."""
    code, d, events = jet_code(scene, events)
    cflags = tuple(cflags)
    if cflags == tuple(DEFAULT_CFLAGS) and len(d.ops) >= LARGE_JET_OPS:
        cflags = LARGE_JET_CFLAGS
    return _built(f"the Taylor jet of model {code.model_name!r}", f"{code.prefix}_taylor", code.files,
                  {"table": f"{code.prefix}_taylor_table"}, (code, d, events), cc=cc, cflags=cflags, verbose=verbose)


def taylor_contact_library(system, scene, events=(), *, cc: str | None = None, verbose: bool = False) -> Library:
    """``<prefix>_taylor_contact_table``: the Taylor jet of the constrained ``system`` with contacts
    (compiled from ``scene``) and its ``events``: its index-1 system of the rows held, for the Taylor contact driver
    (:mod:`lagcodegen.codegen.taylor.contacts`, lagcodegen/runtime/lcg_taylor_imp.c); ``extra``
    (the :class:`~lagcodegen.codegen.record.GeneratedCode`, its
    :class:`~lagcodegen.codegen.taylor.decompose.Decomposition`, its
    :class:`~lagcodegen.codegen.taylor.contacts.ContactRows`)."""
    code, d, rows = contact_jet_code(system, scene, events)
    cflags = LARGE_JET_CFLAGS if len(d.ops) >= LARGE_JET_OPS else DEFAULT_CFLAGS
    return _built(f"the Taylor contact jet of model {code.model_name!r}", f"{code.prefix}_taylor_contact", code.files,
                  {"table": f"{code.prefix}_taylor_contact_table"}, (code, d, rows), cc=cc, cflags=cflags,
                  verbose=verbose)


def taylor_variational_library(code: GeneratedCode, scene, directions: list[tuple[str, int]], names: list[str],
                               events=(), *, cc: str | None = None, verbose: bool = False) -> Library:
    """``<prefix>_taylor_var_table``: the variational jet of ``scene`` (the model compiled as
    ``code``, or a scene derived from it) along ``directions`` named ``names``, with the checked
    ``events`` (:func:`lagcodegen.codegen.taylor.variational_source.variational_sources`);
    ``extra`` (its :class:`~lagcodegen.codegen.taylor.variational.VariationalDecomposition`,)."""
    files, v = variational_sources(scene, directions, names, events=events)
    return _built(f"the Taylor sensitivities of model {code.model_name!r}", f"{scene.prefix}_taylor_var", files,
                  {"table": f"{scene.prefix}_taylor_var_table"}, (v,), cc=cc, verbose=verbose)


def taylor_integrator(scene, events=(), *, cc: str | None = None, cflags: tuple[str, ...] = DEFAULT_CFLAGS,
                      verbose: bool = False) -> tuple[BuiltModule, Decomposition, list]:
    """The standalone Taylor integrator of ``scene`` with ``events`` (checked here), driver
    included (:func:`lagcodegen.codegen.taylor.emit.taylor_code`), compiled into a cffi module of
    its own by :func:`lagcodegen.build.build` (no SUNDIALS): (the built module, its
    :class:`~lagcodegen.codegen.taylor.decompose.Decomposition`, the checked events)."""
    code, d, events = taylor_code(scene, events)
    return build(code, native=False, cc=cc, cflags=cflags, verbose=verbose), d, events
