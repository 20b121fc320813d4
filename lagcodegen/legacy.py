"""The module paths of lagcodegen 0.1 (one flat package), kept importable as aliases.

``from lagcodegen.dae import compile_constrained``, ``from lagcodegen.events import
simulate_with_switch``, ``lagcodegen.routhian.reduce`` ... keep working: each old module name
is a module object holding the public names that module had, taken from where they live now.
New code imports from the stages (``lagcodegen.theory.routhian``, ``lagcodegen.api``, ...).
"""

from __future__ import annotations

import sys
import types

from . import api, build, util
from .codegen import c, constrained as codegen_constrained, fortran, languages, record, templates
from .codegen import bundle
from .formulation import constrained as formulation_constrained, kernels, scene
from .model import events, mechanics, outputs, systems
from .simulation import constrained as solvers_constrained, hybrid, minimal as solvers_minimal, ode
from .solvers import base
from .theory import constraints, energy, forces, linearize, minimal, routhian, steady

#: old module name -> the modules (or (module, names)) its public names come from now.
OLD_MODULES = {
    "events": [events, hybrid],
    "mechanics": [mechanics],
    "systems": [systems],
    "energy": [energy],
    "forces": [forces],
    "linearize": [linearize],
    "steady": [steady],
    "routhian": [routhian],
    "constraints": [constraints],
    "minimal": [minimal, solvers_minimal],
    "scene": [scene, outputs],
    "constrained_codegen": [formulation_constrained, codegen_constrained, outputs],
    "codegen": [c, record, templates, kernels, languages, (util, ["atomic_write"])],
    "fortran": [fortran],
    "bundle": [bundle],
    "solve": [ode, base, (util, ["output_times", "state_vector"])],
    "dae": [solvers_constrained, codegen_constrained, formulation_constrained,
            (api, ["compile_constrained", "FORMULATIONS"]), (outputs, ["CONSTRAINT_OUTPUT_GROUPS"])],
}


def _module(old: str, sources) -> types.ModuleType:
    mod = types.ModuleType(f"lagcodegen.{old}", f"Alias of lagcodegen 0.1's module {old!r} (see lagcodegen.legacy).")
    for src in sources:
        module, names = src if isinstance(src, tuple) else (src, None)
        for name in names or [k for k in vars(module) if not k.startswith("__")]:
            if not hasattr(mod, name):
                setattr(mod, name, getattr(module, name))
    return mod


def install(package: types.ModuleType) -> None:
    """Register the old module names under ``package`` (the lagcodegen package itself)."""
    for old, sources in OLD_MODULES.items():
        sys.modules.setdefault(f"{package.__name__}.{old}", _module(old, sources))
    _ = build  # lagcodegen.build is still the build module (the function lagcodegen.build is api.build)
