"""What one simulation needs: the functions to emit, the run-time parameters, the outputs.

Code generation emits exactly what a :class:`Scene` asks for and nothing more: no Jacobian
unless ``jacobian`` is set, only the requested outputs, and every parameter not listed in
``runtime_parameters`` folded into the code as a constant.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np
import symengine as se

from ..derivation import EquationsOfMotion, to_se
from ..errors import ModelError
from ..model.treedynamics import dag_dependencies, substitute_shared
from ..model.outputs import OUTPUT_GROUPS
from ..util import check_finite



#: Prefixes whose files (<prefix>.h, <prefix>.c) would be the files lagcodegen writes beside
#: them under a fixed name. (Names of system headers, math, stdlib, Python..., are fine: the
#: generated files include each other with quotes, never through -I on their folder.)
RESERVED_PREFIXES = {
    "sundials_api": "sundials_api.h is the SUNDIALS declarations of the native drivers",
    "lcg_codes": "lcg_codes.h is the result codes of the model tables and native drivers",
    "lcg_config": "lcg_config.h is the build configuration of the native drivers",
    "rk4_example": "rk4_example.c is the example program of the bundles",
    "cvode_example": "cvode_example.c is the CVODE example program of the bundles",
}


@dataclass(frozen=True)
class Output:
    """One scalar output: its name and symengine expression in (q, q', t, p)."""

    name: str
    expr: object


@dataclass
class Scene:
    """What to emit for one simulation.

    Parameters
    ----------
    eom:
        The derived equations.
    jacobian:
        Emit the dense Jacobian df/dy (needed by CVODE's Newton iteration unless it uses
        difference quotients).
    outputs:
        Names of outputs: groups ``energy`` (T+V), ``kinetic_energy``, ``potential_energy``,
        ``dissipation`` (D), ``jacobi_h`` (h, eq. 3.5), ``dh_dt`` (its rate, eq. 3.6 with the
        non-potential forces: -2D for homogeneous quadratic dissipation), ``momenta`` (p_<q>, eq. 2.3), ``positions`` (<point>_x/_y/_z of
        every point), single names from those groups (``p_theta``, ``bob_x``), or user outputs
        declared with :meth:`Model.output`.
    runtime_parameters:
        Parameters that stay adjustable at run time (passed in the ``p`` array, in this
        order). ``None`` keeps them all adjustable; the others are folded as constants. The
        model's inputs (:meth:`Model.input`) are always run-time parameters (appended when
        missing from the list).
    values:
        Values for folded parameters, overriding the model's defaults.
    prefix:
        C identifier prefix of the emitted functions (default: the model's name).
    sparse_jacobian:
        Also emit ``<prefix>_jac_sparse`` (files ``<prefix>_sparse.h``/``.c``): only the
        structurally nonzero entries of df/dy (:meth:`jacobian_pattern`), in compressed-column
        order; structurally zero entries are never computed. The native driver uses it with
        ``linear_solver="band"``.
    jacobian_form:
        How the generated code (C and Fortran alike) computes the dense Jacobian: ``"expanded"``
        (every entry of dr/dy, r = M q'' - F, as its own expression: code growing like n^3 for
        a dense coupling),
        ``"tangent"`` (forward-mode differentiation of the right-hand side's program: the
        statements that depend on few columns specialized per column, the others shared by all
        columns; code growing like n^2; :mod:`lagcodegen.formulation.tangent`) or ``"auto"``
        (:func:`auto_jacobian_form`).
    """

    eom: EquationsOfMotion
    jacobian: bool = True
    outputs: Sequence[str] = ()
    runtime_parameters: Sequence[str] | None = None
    values: Mapping[str, float] = field(default_factory=dict)
    prefix: str | None = None
    sparse_jacobian: bool = False
    jacobian_form: str = "auto"

    def __post_init__(self):
        model = self.eom.model
        if self.jacobian_form not in ("auto", "expanded", "tangent"):
            raise ModelError(f"scene: jacobian_form must be 'auto', 'expanded' or 'tangent', "
                             f"got {self.jacobian_form!r}")
        self.prefix = self.prefix or model.name
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", self.prefix):
            raise ModelError(f"scene prefix {self.prefix!r} is not a C identifier")
        if self.prefix in RESERVED_PREFIXES:
            raise ModelError(f"scene prefix {self.prefix!r} is reserved: {RESERVED_PREFIXES[self.prefix]} "
                             f"(give the model another name, or Scene(prefix=...))")
        names = [s.name for s in model.params]
        if self.runtime_parameters is None:
            self.runtime_parameters = list(names)
        else:
            self.runtime_parameters = list(self.runtime_parameters)
            for name in self.runtime_parameters:
                if name not in names:
                    raise ModelError(f"scene: runtime parameter {name!r} is not a parameter of the model "
                                     f"(parameters: {', '.join(names) or 'none'})")
        # An input (Model.input) is a run-time parameter of every scene: a signal is never folded.
        self.runtime_parameters += [u for u in getattr(model, "inputs", ()) if u not in self.runtime_parameters]
        for name, value in self.values.items():
            if name not in names:
                raise ModelError(f"scene: value given for unknown parameter {name!r}")
            check_finite(value, f"scene value of parameter {name!r}")
        self.outputs = list(self.outputs)
        if self.jacobian and not getattr(self.eom, "symmetric", True):
            raise ModelError(f"model {self.eom.model.name!r}: its mass matrix is not symmetric (equations given "
                             "directly): its analytic Jacobian is not generated; use jacobian=False (CVODE forms it "
                             "from differences)")
        if self.sparse_jacobian and self.eom.general:
            model = self.eom.model
            raise ModelError(f"model {model.name!r} has generalized speeds (nq = {model.nq}, nv = {model.nv}): its "
                             "sparse Jacobian is not generated; use the dense one (sparse_jacobian=False)")
        outputs = self.output_list()  # validate names early
        check_double_range([(f"mass matrix entry M[{i}][{j}]", e) for i, row in enumerate(self.eom.M_se) for j, e in enumerate(row)]
                           + [(f"force term F[{i}] (equation of {model.v[i].name if model.general else model.coords[i].name})", e)
                              for i, e in enumerate(self.eom.F_se)]
                           + [(f"output {o.name!r}", o.expr) for o in outputs])

    # ------------------------------------------------------------------ queries
    def resolved_jacobian_form(self) -> str:
        """``jacobian_form`` with "auto" resolved (:func:`auto_jacobian_form`)."""
        if self.jacobian_form != "auto":
            return self.jacobian_form
        if self.eom.tree is not None:  # a rigid-body tree's program: differentiated as a program
            return "tangent"
        return auto_jacobian_form(self.eom.model.n)

    @property
    def folded(self) -> dict[str, float]:
        """Parameters folded into the code as constants, with their values."""
        model = self.eom.model
        vals = {s.name: v for s, v in model.params.items() if s.name not in self.runtime_parameters}
        vals.update({k: float(v) for k, v in self.values.items() if k in vals})
        return vals

    @property
    def input_names(self) -> list[str]:
        """The run-time parameters that are input signals (:meth:`Model.input`), in ``p`` order."""
        inputs = set(getattr(self.eom.model, "inputs", ()))
        return [name for name in self.runtime_parameters if name in inputs]

    def default_parameters(self) -> list[float]:
        """Default values of the run-time parameters, in ``p`` order."""
        d = {s.name: v for s, v in self.eom.model.params.items()}
        return [float(self.values.get(name, d[name])) for name in self.runtime_parameters]

    def available_outputs(self) -> dict[str, object]:
        """Every output a scene can ask for, by name, as symengine expressions."""
        eom = self.eom
        model = eom.model
        out: dict[str, object] = {
            "energy": eom.T_se + eom.V_se,
            "kinetic_energy": eom.T_se,
            "potential_energy": eom.V_se,
            "dissipation": eom.D_se,
            "jacobi_h": eom.h_se,
            "dh_dt": eom.dhdt_se,
        }
        for q, p in zip(model.v if model.general else model.coords, eom.p_se):
            out[f"p_{q.name}"] = p
        for pt in model.points.values():
            for axis, c in zip("xyz", eom.position(pt.name)):
                out[f"{pt.name}_{axis}"] = c
        for name, expr in model.outputs.items():
            out[name] = to_se(expr, f"output {name!r}")
        return out

    def _unknown_output(self, name: str) -> str | None:
        """Why the equations do not determine the output ``name`` (equations given directly without
        their energies, :attr:`EquationsOfMotion.unknown`), or None."""
        unknown = getattr(self.eom, "unknown", None)
        if not unknown or name in self.eom.model.outputs:
            return None
        needs = {"energy": ("T", "V"), "kinetic_energy": ("T",), "potential_energy": ("V",), "dissipation": ("D",),
                 "jacobi_h": ("h",), "dh_dt": ("dhdt",), "momenta": ("momenta",)}.get(name)
        if needs is None and name.startswith("p_") and name[2:] in {v.name for v in self.eom.model.v}:
            needs = ("momenta",)
        for key in needs or ():
            if key in unknown:
                return f"output {name!r}: {unknown[key]}"
        return None

    def output_list(self) -> list[Output]:
        """The outputs this scene emits, groups expanded, in order."""
        avail = self.available_outputs()
        model = self.eom.model
        names: list[str] = []
        for item in self.outputs:
            why = self._unknown_output(item) if isinstance(item, str) else None
            if why:
                raise ModelError(why)
            if item == "momenta":
                names += [f"p_{q.name}" for q in (model.v if model.general else model.coords)]
            elif item == "positions":
                names += [f"{pt.name}_{a}" for pt in model.points.values() for a in "xyz"[:pt.dim]]
            elif item in avail:
                names.append(item)
            else:
                raise ModelError(f"scene: unknown output {item!r} (known: {', '.join(OUTPUT_GROUPS)}, "
                                 f"{', '.join(k for k in avail if k not in OUTPUT_GROUPS)})")
        seen = []
        for n in names:
            if n not in seen:
                seen.append(n)
        states = {"t": "the time"}
        for q, v in zip(model.coords, model.speeds):
            states[q.name], states[v.name] = f"coordinate {q.name!r}", f"the velocity of coordinate {q.name!r}"
        for v in model.velocities:
            states[v.name] = f"the generalized speed {v.name!r}"
        for name, _ in self.eom.quadratures:
            states[name] = f"the quadrature state {name!r}"
        for n in seen:
            if n in states:
                raise ModelError(f"output {n!r} has the name of {states[n]}: its column would replace the state's "
                                 f"in the results (rename the output)")
        return [Output(n, avail[n]) for n in seen]

    def substitutions(self) -> dict:
        """symengine substitution folding constant parameters into numbers."""
        def number(v: float):
            # Integral values fold exactly, so that symbolic simplification can use them.
            return se.Integer(int(v)) if v.is_integer() and abs(v) < 2**53 else se.RealDouble(v)
        return {se.Symbol(k): number(v) for k, v in self.folded.items()}

    def jacobian_pattern(self) -> np.ndarray:
        """Structural nonzero pattern of df/dy (ny x ny booleans), with folded parameters applied.

        With y = (q, q', z): dq'/dq' = I; the accelerations a = M^-1 F depend on y_j if F or a
        row of M coupled to them (through the connected components of M's nonzero graph, which
        M^-1 fills in) depends on y_j; quadrature rates z' on what they contain. The pattern
        is exact up to numerical cancellation (a structurally nonzero entry may be zero).
        """
        eom = self.eom
        model = eom.model
        if model.general:
            return _general_pattern(self)
        n, nz = model.n, len(eom.quadratures)
        ny = 2 * n + nz
        sub = self.substitutions()
        state = ([se.Symbol(q.name) for q in model.coords] + [se.Symbol(v.name) for v in model.speeds]
                 + [se.Symbol(name) for name, _ in eom.quadratures])
        index = {s: j for j, s in enumerate(state)}

        def expr(e):
            e = se.sympify(e)
            return e.xreplace(sub) if sub else e

        if eom.tree is not None:  # DAGs: every distinct subexpression visited once
            deps = dag_dependencies(index)
        else:
            def deps(e) -> set[int]:
                return {index[s] for s in e.free_symbols if s in index}

        if eom.tree is not None:  # one substitution sharing the DAGs' subexpressions across the entries
            flat = substitute_shared(sub, [e for row in eom.M_se for e in row] + list(eom.F_se))
            M, F = [flat[i * n:(i + 1) * n] for i in range(n)], flat[n * n:]
        else:
            M = [[expr(eom.M_se[i][j]) for j in range(n)] for i in range(n)]
            F = [expr(e) for e in eom.F_se]
        nonzero = [[M[i][j] != 0 for j in range(n)] for i in range(n)]
        # dr_i/dy_j with r = M a - F (a generic): F_i and the nonzero entries of row i of M.
        dr = []
        for i in range(n):
            d = deps(F[i])
            for k in range(n):
                if nonzero[i][k]:
                    d |= deps(M[i][k])
            dr.append(d)
        # M^-1 couples every pair of coordinates in one connected component of M's graph.
        find = mass_components(nonzero)
        reach: dict[int, set[int]] = {}
        for i in range(n):
            reach.setdefault(find[i], set()).update(dr[i])
        pattern = np.zeros((ny, ny), dtype=bool)
        for i in range(n):
            pattern[i, n + i] = True
            for j in reach[find[i]]:
                pattern[n + i, j] = True
        for k, (_, rate) in enumerate(eom.quadratures):
            for j in deps(expr(rate)):
                pattern[2 * n + k, j] = True
        return pattern


def mass_components(nonzero: list) -> list[int]:
    """The connected component (a representative index) of each row of a mass matrix whose
    structural nonzeros are ``nonzero`` (M^-1 couples every pair in one component)."""
    n = len(nonzero)
    comp = list(range(n))

    def find(i):
        while comp[i] != i:
            comp[i] = comp[comp[i]]
            i = comp[i]
        return i
    for i in range(n):
        for j in range(i + 1, n):
            if nonzero[i][j] or nonzero[j][i]:
                comp[find(i)] = find(j)
    return [find(i) for i in range(n)]


def _general_pattern(scene) -> np.ndarray:
    """The Jacobian pattern of a model with generalized speeds: q' = k(q, v, t) depends on what
    k_i holds; v' = M^-1 F, for a rigid-body tree, on the whole state (taken dense), otherwise
    as :meth:`Scene.jacobian_pattern`'s accelerations: through the connected components of M's
    nonzero graph, on what F and the nonzero entries of M hold (a coordinate's rate q'_i inside
    them standing for what k_i holds); quadrature rates on what they hold (rates through k)."""
    eom = scene.eom
    model = eom.model
    nq, nv, nz = model.nq, model.nv, len(eom.quadratures)
    ny = nq + nv + nz
    state = ([se.Symbol(q.name) for q in model.coords] + [se.Symbol(v.name) for v in model.velocities]
             + [se.Symbol(name) for name, _ in eom.quadratures])
    index = {s: {j} for j, s in enumerate(state)}
    sub = scene.substitutions()

    def deps(e) -> set:
        e = se.sympify(e)
        e = e.xreplace(sub) if sub else e
        out: set = set()
        for s in e.free_symbols:
            out |= index.get(s, set())
        return out
    pattern = np.zeros((ny, ny), dtype=bool)
    velocities = {v.name for v in model.velocities}
    for i, (k, qd) in enumerate(zip(eom.qdot_se, model.speeds)):
        d = deps(k)
        for j in d:
            pattern[i, j] = True
        if qd.name not in velocities:  # q'_i inside M, F or a rate: what k_i holds
            index[se.Symbol(qd.name)] = d
    if eom.tree is not None:
        pattern[nq:nq + nv, :nq + nv] = True
    else:
        M = [[se.sympify(e) for e in row] for row in eom.M_se]
        nonzero = [[M[a][b] != 0 for b in range(nv)] for a in range(nv)]
        find = mass_components(nonzero)
        reach: dict[int, set] = {}
        for a in range(nv):
            d = deps(eom.F_se[a])
            for b in range(nv):
                if nonzero[a][b]:
                    d |= deps(M[a][b])
            reach.setdefault(find[a], set()).update(d)
        for a in range(nv):
            for j in reach[find[a]]:
                pattern[nq + a, j] = True
    for k, (_, rate) in enumerate(eom.quadratures):
        for j in deps(rate):
            pattern[nq + nv + k, j] = True
    return pattern


def check_double_range(exprs: Sequence[tuple[str, object]]) -> None:
    """Raise ModelError naming the first expression (``(what, symengine expression)`` pairs) that
    holds a number outside double precision range (``1e200*theta`` squared in M: 1e400; the
    expanded coefficients of a high power): printed into C it would be ``inf``. Shared
    subexpressions are visited once (a 20-link chain's M and F: about 10 ms)."""
    seen: set = set()
    for what, expr in exprs:
        stack = [se.sympify(expr)]
        while stack:
            e = stack.pop()
            if e.is_Number:
                try:
                    finite = math.isfinite(float(e))
                except (OverflowError, TypeError, ValueError, RuntimeError):
                    finite = False
                if not finite:
                    text = str(e)
                    text = "" if "inf" in text else f" {text}" if len(text) <= 40 else f" {text[:20]}...{text[-12:]}"
                    raise ModelError(f"{what} holds a number{text} beyond double precision range (the C code would "
                                     f"hold inf): rescale the model (its units), or lower the power that makes it")
                continue
            if e.is_Symbol or e in seen:
                continue
            seen.add(e)
            stack.extend(e.args)


#: Scene(jacobian_form="auto") emits the expanded Jacobian up to this many coordinates and the
#: tangent form above (see auto_jacobian_form for the measurements).
EXPANDED_JACOBIAN_MAX_N = 20


def auto_jacobian_form(n: int) -> str:
    """The Jacobian form of ``Scene(jacobian_form="auto")`` for ``n`` coordinates: "expanded" for
    n <= EXPANDED_JACOBIAN_MAX_N, "tangent" above.

    Both are printed in pieces of bounded length above a few thousand operations (the compiler's
    time then grows like the code's size). Measured (``python benchmarks/scaling.py``, planar
    n-link pendulum, gcc 12 -O2, compiler CPU seconds / jac call in microseconds, expanded vs
    tangent): n = 10: 1.0 / 6.5 vs 1.4 / 13.3; n = 20: 4.4 / 31 vs 5.1 / 62 (generation 2.0 vs
    0.9 s); n = 30: 10.1 / 88 vs 10.6 / 215, but the expanded form's generation (symbolic
    derivatives and their elimination) takes 12.5 s against 4.3 s. Up to 20 coordinates the
    expanded form is as fast to build and runs its Jacobian twice as fast; above, its generation
    grows like n^3.5 and the tangent form builds first (its code grows like n^2 for any coupling;
    the expanded form's like n^3 when every coordinate enters every entry of M)."""
    return "expanded" if n <= EXPANDED_JACOBIAN_MAX_N else "tangent"


def band_order(n: int, nz: int = 0) -> list[int]:
    """State order of the band solver: (q_1, q_1', q_2, q_2', ..., z): element k of the solver's
    vector is y[order[k]]. Interleaving keeps a chain's couplings near the diagonal (in the
    order (q, q') the identity block alone puts n entries above it)."""
    order = []
    for i in range(n):
        order += [i, n + i]
    return order + list(range(2 * n, 2 * n + nz))


def bandwidths(pattern, order: Sequence[int] | None = None) -> tuple[int, int]:
    """(upper, lower) bandwidth of a square nonzero ``pattern`` with rows and columns taken in
    ``order`` (default: as they are)."""
    pattern = np.asarray(pattern, dtype=bool)
    ny = pattern.shape[0]
    inv = np.empty(ny, dtype=int)
    inv[np.asarray(order if order is not None else range(ny), dtype=int)] = np.arange(ny)
    rows, cols = np.nonzero(pattern)
    if rows.size == 0:
        return 0, 0
    d = inv[cols] - inv[rows]
    return int(max(0, d.max())), int(max(0, -d.min()))
