"""The libraries a run asks for beyond a model's own code, generated and compiled by the build
stage on a solver's request: the forward sensitivity functions of a scene
(:func:`sensitivity_library`) and of a constrained system
(:func:`constrained_sensitivity_library`), the event functions (:func:`events_library`) and
their gradients (:func:`events_gradient_library`), the inverse-dynamics regressor
(:func:`regressor_library`).

Each is a :class:`Library`: the open shared library, its path, whether it came from the cache
and the names its C defines. The solvers never generate or compile C themselves: they ask for
the library here (and keep it with the compiled model, :mod:`lagcodegen.solvers.artifacts`);
its sources come from :mod:`lagcodegen.codegen`, its build from :func:`lagcodegen.build.plain_library`,
cached by content like every build."""

from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
from pathlib import Path

from .build import generated_headers, plain_library
from .codegen.events import events_gradient_function, events_gradient_source, events_function, events_source
from .codegen.record import GeneratedCode, scene_of_code
from .codegen.regressor import regressor_files, regressor_functions
from .codegen.sensitivity import sensitivity_source
from .codegen.sensitivity_constrained import constrained_sensitivity_source
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


def _built(label: str, prefix: str, sources: dict, functions: dict, extra: tuple = ()) -> Library:
    handle, path, cached = plain_library(label, prefix, sources)
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
