"""The variables of an FMU and their dependencies, from a scene: one job, the table that both
modelDescription.xml versions (:mod:`.description`) and the C model table (lcg_fmu.h) agree on.

Value references: 0 time; 1..nx the states y = (q, q', z) named as in ``simulate()``'s CSV;
nx+1..2nx their derivatives ``der(<state>)``; then the scene's run-time parameters and inputs in
``p`` order; then the outputs. In the ModelStructure the derivative of q_i (q_i') depends on the
state q_i' alone; an acceleration (eq. 3.2 solved for q'') on the states and inputs that enter
the rows of M q'' = F coupled to it through M (:meth:`Scene.jacobian_pattern`); an output on the
states and inputs of its expression.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Sequence

import symengine as se

from ..formulation.scene import Scene


@dataclass(frozen=True)
class Variable:
    """One Float64 variable of the FMU."""

    name: str
    vr: int
    kind: str  # "time", "state", "derivative", "parameter", "input", "output"
    start: float | None = None
    variability: str = "continuous"  # parameters: "tunable" or "fixed"
    derivative_of: int | None = None  # derivatives: the value reference of the state
    dependencies: tuple[int, ...] | None = None  # value references (states, inputs); None: not listed
    description: str = ""
    unit: str = field(default="", repr=False)  # "": none stated (the FMU's token digests stated units apart)


@dataclass
class VariableTable:
    """Every variable of the FMU, in value-reference order."""

    variables: list[Variable] = field(default_factory=list)
    nx: int = 0
    np: int = 0
    nout: int = 0

    def of_kind(self, *kinds: str) -> list[Variable]:
        return [v for v in self.variables if v.kind in kinds]


def _symbols(expr) -> set[str]:
    return {s.name for s in se.sympify(expr).free_symbols}


def variable_table(scene: Scene, *, x_start: Sequence[float], tunable: set[str]) -> VariableTable:
    """The FMU's variables for ``scene`` (every parameter in ``p``; ``tunable`` names those the
    importer may change during the simulation, the others are fixed after initialization)."""
    eom = scene.eom
    model = eom.model
    nq, n, nz = model.nq, model.nv, len(eom.quadratures)  # n: the speeds (generalized ones: nv <= nq)
    nx = nq + n + nz
    state_names = [q.name for q in model.coords] + [v.name for v in model.v] + [name for name, _ in
                                                                                 eom.quadratures]
    params = list(scene.runtime_parameters)
    inputs = set(scene.input_names)
    outputs = scene.output_list()
    state_vr = {name: 1 + k for k, name in enumerate(state_names)}
    param_vr = {name: 1 + 2 * nx + k for k, name in enumerate(params)}
    input_vr = {name: vr for name, vr in param_vr.items() if name in inputs}

    def deps_of(names: set[str]) -> tuple[int, ...]:
        return tuple(sorted({state_vr[s] for s in names if s in state_vr} | {input_vr[s] for s in names
                                                                               if s in input_vr}))

    # Accelerations: the states of the Jacobian pattern's rows and the inputs of the coupled rows of M, F.
    pattern = scene.jacobian_pattern()
    row_syms = []
    for i in range(n):
        syms = _symbols(eom.F_se[i])
        for k in range(n):
            syms |= _symbols(eom.M_se[i][k])
        row_syms.append(syms)
    comp = list(range(n))

    def find(i: int) -> int:
        while comp[i] != i:
            comp[i] = comp[comp[i]]
            i = comp[i]
        return i
    for i in range(n):
        for k in range(n):
            if i != k and se.sympify(eom.M_se[i][k]) != 0:
                comp[find(i)] = find(k)
    comp_inputs: dict[int, set[str]] = {}
    for i in range(n):
        comp_inputs.setdefault(find(i), set()).update(row_syms[i] & inputs)

    derivative_deps = []
    for k in range(nx):
        if k < nq and not model.general:
            derivative_deps.append((state_vr[state_names[n + k]],))
            continue
        names = {state_names[j] for j in range(nx) if pattern[k, j]}
        if nq <= k < nq + n:
            names |= comp_inputs[find(k - nq)]
        elif k >= nq + n:
            names |= _symbols(eom.quadratures[k - nq - n][1]) & inputs
        derivative_deps.append(deps_of(names))
    defaults = scene.default_parameters()
    param_rows = [(name, defaults[k], "input" if name in inputs else "parameter",
                   "tunable" if name in tunable else "fixed", "") for k, name in enumerate(params)]
    output_rows = [(out.name, deps_of(_symbols(out.expr))) for out in outputs]
    return build_table(state_names, x_start, derivative_deps, param_rows, output_rows, units=stated_units(model))


def stated_units(model) -> dict[str, str]:
    """The units of the FMU's variables from the model's (:meth:`Model.unit`): a coordinate's,
    its velocity's and derivatives' ("<unit>/s", "<unit>/s2"), the parameters' and inputs'."""
    units = {}
    for q, v in zip(model.coords, model.speeds):
        u = model.units.get(q.name)
        if u:
            units.update({q.name: u, v.name: f"{u}/s", f"der({q.name})": f"{u}/s", f"der({v.name})": f"{u}/s2"})
    units.update({s.name: model.units[s.name] for s in model.params if s.name in model.units})
    return units


def build_table(state_names: list[str], x_start: list[float], derivative_deps: list[tuple[int, ...] | None],
                params: list[tuple[str, float, str, str, str]],
                outputs: list[tuple[str, tuple[int, ...] | None]], units: dict | None = None) -> VariableTable:
    """The table in value-reference order: ``params`` rows are (name, start, "parameter" or
    "input", "tunable" or "fixed", description), ``outputs`` rows (name, dependencies); None
    dependencies are not listed (the variable depends on every state and input); ``units``:
    variable name -> unit, where stated."""
    nx = len(state_names)
    table = VariableTable(nx=nx, np=len(params), nout=len(outputs))
    units = units or {}

    def add(v: Variable) -> None:
        table.variables.append(v if v.name not in units else replace(v, unit=units[v.name]))
    add(Variable("time", 0, "time", description="time"))
    for k, name in enumerate(state_names):
        add(Variable(name, 1 + k, "state", start=float(x_start[k])))
    for k, name in enumerate(state_names):
        add(Variable(f"der({name})", 1 + nx + k, "derivative", derivative_of=1 + k, dependencies=derivative_deps[k]))
    for k, (name, start, kind, variability, description) in enumerate(params):
        if kind == "input":
            add(Variable(name, 1 + 2 * nx + k, "input", start=float(start), description=description or "input signal"))
        else:
            add(Variable(name, 1 + 2 * nx + k, "parameter", start=float(start), variability=variability,
                         description=description))
    for k, (name, deps) in enumerate(outputs):
        add(Variable(name, 1 + 2 * nx + len(params) + k, "output", dependencies=deps))
    return table
