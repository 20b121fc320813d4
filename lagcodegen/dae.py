"""Constrained dynamics in generated C: index-1 on CVODE, GGL on IDA, minimal coordinates.

:func:`compile_constrained` turns a :class:`~lagcodegen.constraints.ConstrainedSystem` into
compiled code with one of three formulations of the equations with multipliers (eq. 4.5)

    M q'' = F + A^T lambda,   A q' + A0 = 0   (eqs. 4.2, 4.3; f(q, t) = 0, eq. 4.1, for holonomic rows)

* ``"index1"``: differentiate every constraint to the acceleration level, A q'' = gamma, and
  solve the augmented (n+J) x (n+J) system [M A^T; A 0][q''; -lambda] = [F; gamma - stab]
  numerically in C (dense LU with partial pivoting) at every right-hand-side call; integrate
  y = (q, q') with CVODE (difference-quotient Jacobian). Drift of f(q) and A q' + A0 is
  controlled by Baumgarte stabilization (f'' + 2 alpha f' + beta^2 f = 0 for holonomic rows,
  s' + alpha s = 0 for nonholonomic rows s = A q' + A0) and/or by projection onto the
  constraint manifold after each step through CVODE's own projection interface
  (CVodeSetProjFn: Gauss-Newton q <- q - A^T (A A^T)^{-1} f, then q' onto A q' + A0 = 0;
  CVODE only allows it with BDF).
* ``"ggl"``: the stabilized index-2 DAE of Gear, Gupta and Leimkuhler for IDA, unknowns
  (q, v, lambda, mu) and residual [q' - v - A_h^T mu; M v' - F - A^T lambda; f(q, t); A v + A0]
  (nonholonomic rows: only the velocity row, no mu). lambda, mu are algebraic (IDASetId) and
  left out of the error test (IDASetSuppressAlg) on the native driver; the residual Jacobian
  dF/dy + cj dF/dy' is generated symbolically. Consistent initial values: q0, v0 are checked
  (or projected), lambda and y' are computed from the augmented system and polished by
  IDACalcIC(IDA_YA_YDP_INIT).
* ``"minimal"``: holonomic constraints solved symbolically (sympy) for some coordinates,
  substituted into the model to give an unconstrained model in the remaining coordinates.

All return a :class:`~lagcodegen.result.Result` with y = (q, q') (minimal: the remaining
coordinates; the eliminated ones are outputs), outputs ``lambda_<j>``, ``g_<j>`` (f_j(q, t),
holonomic j), ``gdot_<j>`` (A_j q' + A0_j), ``energy`` (T + V), and on request the
constraint forces ``R_<j>_<coordinate>`` = lambda_j A_j (sec. 4.3), and ``events``.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field
from typing import Iterable, Mapping, Sequence

import numpy as np
import symengine as se
import sympy as sp

from . import __version__
from .build import CompiledModel, build
from .codegen import _symbol_map, emit_block, environment, generate_c
from .constraints import ConstrainedSystem
from .derivation import derive, to_se
from .errors import LagcodegenError, ModelError, SingularMassMatrixError, SolverError
from .events import Event, EventRecord, event_list, records
from .model import Model, check_finite
from .result import Result
from .scene import Scene
from .solve import CVODE_FLAG_TEXT, output_times, state_vector

FORMULATIONS = ("index1", "ggl", "minimal")
#: Output groups of constrained systems, besides the model's (energy, positions, momenta...).
CONSTRAINT_OUTPUT_GROUPS = ("lambda", "constraint_forces", "residuals", "inequalities")
DEFAULT_OUTPUTS = ("energy", "lambda", "residuals")
METHODS = {"adams": 1, "bdf": 2}
#: Error codes of the generated constrained functions (<prefix>_dae.h).
ERR_SINGULAR, ERR_NONFINITE, ERR_PROJECTION = 1, 2, 3
#: Default absolute tolerance of the algebraic GGL unknowns lambda, mu. scikit-sundae never
#: calls IDASetSuppressAlg, so there a huge atol is what keeps them out of the error test. The
#: native driver excludes them from the error test with IDASetSuppressAlg, but IDA's Newton
#: convergence test (and IDACalcIC's) still weighs every component, and in the index-2 system
#: round-off in q reaches lambda amplified by cj^2 = O(1/h^2): with a tight atol on lambda the
#: corrector fails to converge (observed for atol <= 1e-4 at rtol = 1e-10), so the native
#: driver uses the same loose value for lambda, mu by default (``alg_atol``).
ALGEBRAIC_ATOL = 1e8
SKSUNDAE_ALGEBRAIC_ATOL = ALGEBRAIC_ATOL


# ---------------------------------------------------------------------- symbolic pieces
class _Symbolic:
    """symengine pieces of a constrained system: M, F, A, A0, s = A q' + A0, gamma, f."""

    def __init__(self, system: ConstrainedSystem, eom):
        model = system.model
        self.system = system
        self.eom = eom
        self.n = model.n
        self.q = [se.Symbol(s.name) for s in model.coords]
        self.v = [se.Symbol(s.name) for s in model.speeds]
        self.t = se.Symbol(model.t.name)
        rows = system.rows()
        self.A = [[to_se(a, f"constraint {r.index}") for a in r.A] for r in rows]
        self.A0 = [to_se(r.A0, f"constraint {r.index}") for r in rows]
        self.f = [to_se(f, f"holonomic constraint {j}") for j, f in enumerate(system.holonomic)]
        self.s = [sum((a * v for a, v in zip(row, self.v)), se.Integer(0)) + a0 for row, a0 in zip(self.A, self.A0)]
        self.gamma = []
        for s in self.s:  # gamma = -d/dt (A q' + A0) with q'' excluded
            d = se.diff(s, self.t)
            for q, v in zip(self.q, self.v):
                d = d + se.diff(s, q) * v
            self.gamma.append(-d)
        self.lam = [se.Symbol(m.name) for m in system.multipliers]
        self.J = len(rows)
        self.JH = len(self.f)
        self.M = eom.M_se
        self.F = eom.F_se


def _constrained_outputs(system: ConstrainedSystem, sym: _Symbolic, scene: Scene,
                         names: Sequence[str]) -> list[tuple[str, object]]:
    """(name, symengine expression) of the requested outputs, groups expanded."""
    model = system.model
    avail = dict(scene.available_outputs())
    coord_names = [q.name for q in model.coords]
    lam_names, force_names, resid_names, ineq_names = [], [], [], []
    for j in range(sym.J):
        avail[f"lambda_{j}"] = sym.lam[j]
        lam_names.append(f"lambda_{j}")
        for i, c in enumerate(coord_names):
            avail[f"R_{j}_{c}"] = sym.lam[j] * sym.A[j][i]
            force_names.append(f"R_{j}_{c}")
    for j in range(sym.JH):
        avail[f"g_{j}"] = sym.f[j]
        resid_names.append(f"g_{j}")
    for j in range(sym.J):
        avail[f"gdot_{j}"] = sym.s[j]
        resid_names.append(f"gdot_{j}")
    for k, g in enumerate(system.inequalities):
        avail[f"ineq_{k}"] = to_se(g, f"inequality constraint {k}")
        ineq_names.append(f"ineq_{k}")
    groups = {"lambda": lam_names, "constraint_forces": force_names, "residuals": resid_names,
              "inequalities": ineq_names,
              "momenta": [f"p_{c}" for c in coord_names],
              "positions": [f"{pt.name}_{a}" for pt in model.points.values() for a in "xyz"[:pt.dim]]}
    out: list[str] = []
    for item in names:
        if item in groups:
            out += groups[item]
        elif item in avail:
            out.append(item)
        else:
            raise ModelError(f"unknown output {item!r} (groups: {', '.join(CONSTRAINT_OUTPUT_GROUPS)}, "
                             f"energy, momenta, positions, ...; single outputs: "
                             f"{', '.join(k for k in avail if k not in ('momenta', 'positions'))})")
    seen: list[str] = []
    for nme in out:
        if nme not in seen:
            seen.append(nme)
    return [(nme, avail[nme]) for nme in seen]


def _uses(exprs, symbols) -> bool:
    symbols = set(symbols)
    return any(se.sympify(e).free_symbols & symbols for e in exprs)


# ---------------------------------------------------------------------- code generation
@dataclass
class ConstrainedCodeInfo:
    """Layout of the generated constrained code."""

    prefix: str
    n: int
    J: int
    JH: int
    ng: int
    output_names: list
    events: list
    ggl: bool
    ggl_jac: bool
    folded: dict = field(default_factory=dict)  # parameters folded into the code, with their values


def generate_constrained_c(system: ConstrainedSystem, *, ggl: bool = False, ggl_jacobian: bool = True,
                           outputs: Sequence[str] = DEFAULT_OUTPUTS, events: Iterable = (),
                           runtime_parameters=None, values=None, prefix: str | None = None):
    """Generated C of a constrained system: the model's own files plus ``<prefix>_dae.[ch]``
    (augmented-system solve, projection, outputs, roots, GGL residual and Jacobian) and the
    native drivers ``<prefix>_cvc.[ch]`` (CVODE) and, with ``ggl``, ``<prefix>_ida.[ch]`` (IDA).

    Returns (GeneratedCode ready for :func:`lagcodegen.build.build`, ConstrainedCodeInfo).
    """
    model = system.model
    eom = derive(model)
    if eom.quadratures:
        raise ModelError("constrained systems with quadrature states are not supported")
    scene = Scene(eom, jacobian=False, outputs=(), runtime_parameters=runtime_parameters,
                  values=dict(values or {}), prefix=prefix)
    code = generate_c(scene)
    sym = _Symbolic(system, eom)
    n, J, JH = sym.n, sym.J, sym.JH
    ng = 2 * n + J + JH
    base = _symbol_map(scene)

    def c(e, sub=base):
        return se.sympify(e).xreplace(sub)

    # M, F
    targets, exprs = [], []
    for i in range(n):
        for j in range(i, n):
            targets.append(f"M[{i}][{j}]" if i == j else f"M[{i}][{j}] = M[{j}][{i}]")
            exprs.append(c(sym.M[i][j]))
    for i in range(n):
        targets.append(f"F[{i}]")
        exprs.append(c(sym.F[i]))
    mf = emit_block(targets, exprs)
    # A, s, g
    targets, exprs = [], []
    for r in range(J):
        for i in range(n):
            targets.append(f"A[{r}][{i}]")
            exprs.append(c(sym.A[r][i]))
        targets.append(f"s[{r}]")
        exprs.append(c(sym.s[r]))
    for k in range(JH):
        targets.append(f"g[{k}]")
        exprs.append(c(sym.f[k]))
    con = emit_block(targets, exprs)
    gam = emit_block([f"gam[{r}]" for r in range(J)], [c(e) for e in sym.gamma])

    # outputs and roots: the multipliers are the array lam[]
    out_sub = dict(base)
    out_sub.update({lam: se.Symbol(f"lam[{j}]") for j, lam in enumerate(sym.lam)})
    outs = _constrained_outputs(system, sym, scene, list(outputs))
    out_block = emit_block([f"out[{k}]" for k in range(len(outs))], [c(e, out_sub) for _, e in outs])
    evs = event_list(system, events)
    root_exprs = [to_se(ev.expr, f"event {ev.name!r}") for ev in evs]
    root_block = emit_block([f"gout[{k}]" for k in range(len(evs))], [c(e, out_sub) for e in root_exprs])

    # GGL residual and Jacobian
    ggl_res = ggl_jac_block = ""
    if ggl:
        qp = [se.Symbol(f"__qp{i}") for i in range(n)]
        vp = [se.Symbol(f"__vp{i}") for i in range(n)]
        mu = [se.Symbol(f"__mu{k}") for k in range(JH)]
        cj = se.Symbol("cj")
        res = []
        for i in range(n):
            res.append(qp[i] - sym.v[i] - sum((sym.A[k][i] * mu[k] for k in range(JH)), se.Integer(0)))
        for i in range(n):
            res.append(sum((sym.M[i][j] * vp[j] for j in range(n)), se.Integer(0)) - sym.F[i]
                       - sum((sym.A[r][i] * sym.lam[r] for r in range(J)), se.Integer(0)))
        res += list(sym.f)
        res += list(sym.s)
        gsub = dict(base)
        gsub.update({lam: se.Symbol(f"y[{2 * n + j}]") for j, lam in enumerate(sym.lam)})
        gsub.update({m: se.Symbol(f"y[{2 * n + J + k}]") for k, m in enumerate(mu)})
        gsub.update({x: se.Symbol(f"yp[{i}]") for i, x in enumerate(qp)})
        gsub.update({x: se.Symbol(f"yp[{n + i}]") for i, x in enumerate(vp)})
        ggl_res = emit_block([f"rr[{i}]" for i in range(ng)], [c(e, gsub) for e in res])
        if ggl_jacobian:
            yvars = sym.q + sym.v + sym.lam + mu
            ypvars = qp + vp
            targets, exprs = [], []
            for col, var in enumerate(yvars):
                for row, r in enumerate(res):
                    d = se.diff(r, var)
                    if col < 2 * n:
                        d = d + cj * se.diff(r, ypvars[col])
                    if d != 0:
                        targets.append(f"jac[{col * ng + row}]")
                        exprs.append(c(d, gsub))
            ggl_jac_block = emit_block(targets, exprs)

    pre = code.prefix
    ctx = dict(prefix=pre, PREFIX=pre.upper(), version=__version__, model_name=model.name, n=n, nj=J, njh=JH,
               ng=ng, np=len(scene.runtime_parameters), nout=len(outs), nroot=len(evs),
               state_names=code.state_names, param_names=list(scene.runtime_parameters),
               outputs=[name for name, _ in outs], roots=[f"{ev.name}: {ev.expr}" for ev in evs],
               ggl=ggl, ggl_jac=bool(ggl and ggl_jacobian), mf=mf, con=con, gam=gam, out=out_block,
               outputs_use_lam=_uses([e for _, e in outs], sym.lam), root_block=root_block,
               roots_use_lam=_uses(root_exprs, sym.lam), ggl_res=ggl_res, ggl_jac_block=ggl_jac_block)
    env = environment()
    files = {
        f"{pre}_dae.h": env.get_template("c/dae.h.j2").render(**ctx),
        f"{pre}_dae.c": env.get_template("c/dae.c.j2").render(**ctx),
        f"{pre}_cvc.h": env.get_template("c/cvode_constrained_driver.h.j2").render(**ctx),
        f"{pre}_cvc.c": env.get_template("c/cvode_constrained_driver.c.j2").render(**ctx),
    }
    headers = [f"{pre}_dae.h", f"{pre}_cvc.h"]
    if ggl:
        files[f"{pre}_ida.h"] = env.get_template("c/ida_driver.h.j2").render(**ctx)
        files[f"{pre}_ida.c"] = env.get_template("c/ida_driver.c.j2").render(**ctx)
        headers.append(f"{pre}_ida.h")
        code.sundials_libs = tuple(dict.fromkeys((*code.sundials_libs, "ida")))
    code.files.update(files)
    code.cffi_headers = list(dict.fromkeys([*code.cffi_headers, *headers]))
    code.cdef_extra = (code.cdef_extra + "\n" + _cdef(pre, bool(evs), ggl, bool(ggl and ggl_jacobian))).strip()
    info = ConstrainedCodeInfo(pre, n, J, JH, ng, [name for name, _ in outs], evs, ggl, bool(ggl and ggl_jacobian),
                               dict(scene.folded))
    return code, info


def _cdef(p: str, roots: bool, ggl: bool, ggl_jac: bool) -> str:
    """cffi declarations (API mode: the struct layouts come from the headers via '...;')."""
    lines = [f"""
typedef struct {{
    int max_events; int n_events; double *t; double *y; int *which; int *direction;
    const int *rootdir; const int *terminal; int terminated; ...;
}} {p}_events;
int {p}_kkt(double t, const double *y, const double *p, double alpha, double beta, double *acc, double *lam);
int {p}_crhs(double t, const double *y, const double *p, double alpha, double beta, double *ydot);
int {p}_residuals(double t, const double *y, const double *p, double *g, double *s);
int {p}_project(double t, const double *y, const double *p, double tol, int maxit, double *ynew, double *err);
int {p}_coutputs(double t, const double *y, const double *lam, const double *p, double *out);
typedef struct {{
    int method; double rtol; double atol; const double *atol_vec; long max_steps; double first_step;
    double max_step; double min_step; int max_order; double alpha; double beta; int projection;
    double proj_tol; int proj_maxit; int proj_err; int roots; ...;
}} {p}_cvc_options;
typedef struct {{
    long nsteps, nrhs, nrhs_dq, njac, nlinsetups, netfails, nniters, nncfails, nproj, nprojfails, ngevals;
    double t_reached; double h_last; int flag; int model_error; int nt_done; char message[512]; ...;
}} {p}_cvc_stats;
int {p}_cvc_solve(const double *p, const double *y0, int nt, const double *tout, double *yout, double *out,
                  const {p}_cvc_options *opt, {p}_cvc_stats *st, {p}_events *ev);"""]
    if roots:
        lines.append(f"int {p}_roots(double t, const double *y, const double *lam, const double *p, double *gout);")
    if ggl:
        lines.append(f"""
int {p}_ggl_res(double t, const double *yy, const double *yp, const double *p, double *rr);
typedef struct {{
    double rtol; double atol; const double *atol_vec; long max_steps; double first_step; double max_step;
    double min_step; int max_order; int suppress_alg; int jacobian; int calc_ic; double ic_alg_atol; int roots;
    int stop_at_outputs; ...;
}} {p}_ida_options;
typedef struct {{
    long nsteps, nres, nres_dq, njac, nlinsetups, netfails, nniters, nncfails, nbacktracks, ngevals;
    double t_reached; double h_last; int flag; int ic_flag; int model_error; int nt_done; char message[512]; ...;
}} {p}_ida_stats;
int {p}_ida_solve(const double *p, const double *yy0, const double *yp0, int nt, const double *tout,
                  double *yout, double *out, const {p}_ida_options *opt, {p}_ida_stats *st, {p}_events *ev);""")
        if ggl_jac:
            lines.append(f"int {p}_ggl_jac(double t, double cj, const double *yy, const double *yp, "
                         f"const double *p, double *jac);")
    return "\n".join(lines)


# ---------------------------------------------------------------------- public API
def compile_constrained(system: ConstrainedSystem, formulation: str = "index1", outputs: Sequence[str] | None = None,
                        baumgarte: tuple[float, float] = (0.0, 0.0), projection: bool = False,
                        events: Iterable = (), runtime_parameters=None, values: Mapping | None = None,
                        prefix: str | None = None, jacobian: bool = True, eliminate: Sequence | None = None,
                        verbose: bool = False):
    """Generate and compile a constrained system (eq. 4.5) in one formulation.

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
        Default (alpha, beta) of the index-1 formulation (0, 0: none); simulate() may override.
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
    """
    if not isinstance(system, ConstrainedSystem):
        raise ModelError(f"compile_constrained needs a ConstrainedSystem, got {type(system).__name__}")
    if formulation not in FORMULATIONS:
        raise ModelError(f"formulation must be one of {', '.join(FORMULATIONS)}, got {formulation!r}")
    alpha, beta = (check_finite(x, "baumgarte parameter") for x in baumgarte)
    if formulation == "minimal":
        return MinimalSimulation(system, outputs=outputs, events=events, runtime_parameters=runtime_parameters,
                                 values=values, prefix=prefix, eliminate=eliminate, verbose=verbose)
    if outputs is None:
        outputs = DEFAULT_OUTPUTS
    code, info = generate_constrained_c(system, ggl=formulation == "ggl", ggl_jacobian=jacobian, outputs=outputs,
                                        events=events, runtime_parameters=runtime_parameters, values=values,
                                        prefix=prefix)
    cm = build(code, native=True, verbose=verbose)
    return ConstrainedSimulation(system, formulation, cm, info, (alpha, beta), bool(projection))


_CV_TEXT = {
    **CVODE_FLAG_TEXT,
    -12: "a root (event) function failed",
    -30: "the projection onto the constraints failed unrecoverably",
    -31: "the projection onto the constraints failed repeatedly",
}
_IDA_TEXT = {
    -1: "too many steps (max_steps reached); raise max_steps or loosen the tolerances",
    -2: "tolerance too tight for machine precision",
    -3: "error test failed repeatedly or with |h| = hmin",
    -4: "Newton iteration failed to converge repeatedly",
    -6: "the linear solver setup failed (singular iteration matrix?)",
    -7: "the linear solve failed",
    -8: "the residual failed unrecoverably",
    -9: "the residual failed repeatedly with recoverable errors (non-finite values)",
    -10: "a root (event) function failed",
    -12: "the residual failed at the first call",
    -13: "IDACalcIC: line search failed (no consistent lambda and y' found)",
    -14: "IDACalcIC: the residual failed; no consistent initial values",
}


def _message(flag: int, model_error: int, detail: str, table: dict, solver: str) -> str:
    if flag >= 0:
        return "success"
    if model_error == ERR_SINGULAR:
        return "the augmented matrix [M A^T; A 0] is singular (M singular or the constraint Jacobian A rank deficient)"
    if model_error == ERR_NONFINITE:
        return "a computed value is not finite"
    text = table.get(flag, f"{solver} failed with flag {flag}")
    return f"{text}: {detail}" if detail else text


class _Base:
    """What every compiled constrained system offers: layout, parameters, initial-state checks."""

    system: ConstrainedSystem

    @property
    def n(self) -> int:
        return self.system.n

    def _effective_params(self, scene_defaults: dict, p_names: list, p: np.ndarray) -> dict:
        vals = dict(scene_defaults)
        vals.update(zip(p_names, (float(x) for x in p)))
        return vals


class ConstrainedSimulation(_Base):
    """A compiled constrained system (formulation ``index1`` or ``ggl``); call :meth:`simulate`."""

    def __init__(self, system: ConstrainedSystem, formulation: str, cm: CompiledModel, info: ConstrainedCodeInfo,
                 baumgarte: tuple[float, float], projection: bool):
        self.system = system
        self.formulation = formulation
        self.compiled = cm
        self.info = info
        self.baumgarte = baumgarte
        self.projection = projection
        self.ffi, self.lib = cm.ffi, cm.lib
        p = info.prefix
        self._kkt = getattr(self.lib, f"{p}_kkt")
        self._crhs = getattr(self.lib, f"{p}_crhs")
        self._resid = getattr(self.lib, f"{p}_residuals")
        self._project = getattr(self.lib, f"{p}_project")
        self._cout = getattr(self.lib, f"{p}_coutputs")
        self._roots = getattr(self.lib, f"{p}_roots", None)
        self._ggl_res = getattr(self.lib, f"{p}_ggl_res", None)
        self._ggl_jac = getattr(self.lib, f"{p}_ggl_jac", None)

    # ------------------------------------------------------------------ layout
    @property
    def state_names(self) -> list[str]:
        return self.compiled.state_names[: 2 * self.n]

    @property
    def param_names(self) -> list[str]:
        return self.compiled.param_names

    @property
    def output_names(self) -> list[str]:
        return list(self.info.output_names)

    @property
    def events(self) -> list[Event]:
        return list(self.info.events)

    def parameter_vector(self, params: Mapping | None = None) -> np.ndarray:
        return self.compiled.parameter_vector(params)

    def _ptr(self, arr):
        return self.ffi.from_buffer("double[]", arr) if arr.size else self.ffi.NULL

    def _p(self, params):
        return params if isinstance(params, np.ndarray) else self.parameter_vector(params)

    # ------------------------------------------------------------------ generated functions
    def kkt(self, t: float, y, params=None, alpha: float = 0.0, beta: float = 0.0):
        """(q'', lambda) from the augmented system at (t, y)."""
        y = np.ascontiguousarray(y, dtype=float)
        p = self._p(params)
        acc, lam = np.empty(self.n), np.empty(max(self.info.J, 1))
        rc = self._kkt(float(t), self._ptr(y), self._ptr(p), float(alpha), float(beta), self._ptr(acc), self._ptr(lam))
        self._check(rc, t, "augmented system")
        return acc, lam[: self.info.J]

    def residuals(self, t: float, y, params=None):
        """(f(q, t) of the holonomic constraints, A q' + A0 of every constraint)."""
        y = np.ascontiguousarray(y, dtype=float)
        p = self._p(params)
        g, s = np.empty(max(self.info.JH, 1)), np.empty(max(self.info.J, 1))
        rc = self._resid(float(t), self._ptr(y), self._ptr(p), self._ptr(g), self._ptr(s))
        self._check(rc, t, "constraint residuals")
        return g[: self.info.JH], s[: self.info.J]

    def project(self, t: float, y, params=None, tol: float = 1e-14, maxit: int = 50) -> np.ndarray:
        """y projected onto f(q, t) = 0 (Gauss-Newton) and A q' + A0 = 0."""
        y = np.ascontiguousarray(y, dtype=float)
        p = self._p(params)
        out = np.empty_like(y)
        rc = self._project(float(t), self._ptr(y), self._ptr(p), float(tol), int(maxit), self._ptr(out), self.ffi.NULL)
        if rc == ERR_PROJECTION:
            g, s = self.residuals(t, y, p)
            raise ModelError(f"cannot project the initial state onto the constraints: Gauss-Newton did not "
                             f"converge in {maxit} steps (at the start |f(q)| = {_norm(g):.3g}, "
                             f"|A q' + A0| = {_norm(s):.3g})")
        if rc == ERR_SINGULAR:
            raise ModelError("cannot project the initial state onto the constraints: A A^T is singular "
                             "(the constraint Jacobian is rank deficient on the way)")
        self._check(rc, t, "projection")
        return out

    def outputs(self, t: float, y, params=None, lam=None) -> np.ndarray:
        """Outputs at (t, y) (lambda from the augmented system unless given)."""
        y = np.ascontiguousarray(y, dtype=float)
        p = self._p(params)
        out = np.empty(max(len(self.info.output_names), 1))
        lp = self.ffi.NULL if lam is None else self._ptr(np.ascontiguousarray(lam, dtype=float))
        rc = self._cout(float(t), self._ptr(y), lp, self._ptr(p), self._ptr(out))
        self._check(rc, t, "outputs")
        return out[: len(self.info.output_names)]

    def roots(self, t: float, y, params=None, lam=None) -> np.ndarray:
        """Event functions at (t, y)."""
        if self._roots is None:
            return np.empty(0)
        y = np.ascontiguousarray(y, dtype=float)
        p = self._p(params)
        out = np.empty(len(self.info.events))
        lp = self.ffi.NULL if lam is None else self._ptr(np.ascontiguousarray(lam, dtype=float))
        rc = self._roots(float(t), self._ptr(y), lp, self._ptr(p), self._ptr(out))
        self._check(rc, t, "event functions")
        return out

    @staticmethod
    def _check(rc: int, t: float, what: str) -> None:
        if rc == ERR_SINGULAR:
            raise SingularMassMatrixError(f"{what}: the augmented matrix [M A^T; A 0] is singular "
                                          "(M singular or A rank deficient)", t=float(t))
        if rc:
            raise SolverError(f"{what}: a computed value is not finite (code {rc})", t=float(t))

    # ------------------------------------------------------------------ initial state
    def consistent_initial_state(self, t0: float, q0, v0, params=None, initial: str = "check",
                                 ic_tol: float = 1e-8) -> np.ndarray:
        """(q0, v0) checked against (``"check"``) or projected onto (``"project"``) the constraints.

        ``"check"`` raises ModelError for a rank-deficient constraint Jacobian or residuals above
        ``ic_tol`` (and then removes the remaining round-off by a projection); ``"project"``
        projects by Gauss-Newton and raises ModelError, with the residual norms, when that
        fails; ``"none"`` takes the state as it is.
        """
        names = [q.name for q in self.system.model.coords]
        q = state_vector(q0, names, "q0")
        v = state_vector(v0, names, "v0")
        p = self._p(params)
        vals = self._effective_params(self.info.folded, self.param_names, p)
        y = np.concatenate([q, v])
        if initial == "none":
            return y
        if initial not in ("check", "project"):
            raise LagcodegenError(f"initial must be 'check', 'project' or 'none', got {initial!r}")
        if initial == "check":
            self.system.check_initial(q, v, vals, t0=t0, tol=ic_tol)
            return self.project(t0, y, p)
        # project: rank first (clear message), then Gauss-Newton, then verify
        ev = self.system.evaluate(q, v, vals, t0)
        if self.system.J:
            from .constraints import _dependent_rows, _rank_tol
            A = ev["A"]
            if np.linalg.matrix_rank(A, tol=_rank_tol(A)) < self.system.J:
                raise ModelError("singular constraint Jacobian at the initial state: cannot project; "
                                 + _dependent_rows(A))
        yp = self.project(t0, y, p)
        g, s = self.residuals(t0, yp, p)
        if _norm(g) > ic_tol or _norm(s) > ic_tol:
            raise ModelError(f"cannot make the initial state consistent: after projection |f(q)| = {_norm(g):.3g}, "
                             f"|A q' + A0| = {_norm(s):.3g} (tolerance {ic_tol:.3g})")
        return yp

    # ------------------------------------------------------------------ simulate
    def simulate(self, t, q0=None, v0=None, params: Mapping | None = None, rtol: float = 1e-8, atol=1e-10,
                 backend: str = "native", method: str | None = None, baumgarte: tuple | None = None,
                 projection: bool | None = None, initial: str = "check", ic_tol: float = 1e-8,
                 max_steps: int = 1_000_000, first_step: float = 0.0, max_step: float = 0.0,
                 min_step: float = 0.0, max_order: int = 0, events: bool = True, max_events: int = 10_000,
                 suppress_alg: bool = True, alg_atol: float | None = None, jacobian: bool | None = None,
                 stop_at_outputs: bool = True, proj_tol: float = 1e-12,
                 proj_maxit: int = 10, raise_on_error: bool = True) -> Result:
        """Integrate from t[0] and return the trajectory at the times ``t``.

        ``q0``/``v0``: initial coordinates and velocities (arrays or dicts by name), checked or
        projected per ``initial`` (see :meth:`consistent_initial_state`). ``backend``:
        ``"native"`` (generated CVODE/IDA drivers) or ``"sksundae"`` (scikit-sundae's Python API
        on the same compiled functions; index-1 there has no projection, and GGL there uses a
        huge atol on lambda, mu instead of IDASetSuppressAlg).

        Index-1: ``method`` ``"adams"`` (default without projection) or ``"bdf"`` (default and
        required with projection); ``baumgarte=(alpha, beta)`` and ``projection`` override the
        compiled defaults. GGL: ``suppress_alg`` (native), ``jacobian`` (generated residual
        Jacobian, default when compiled), ``alg_atol`` (absolute tolerance of lambda, mu;
        default :data:`ALGEBRAIC_ATOL`, see there), ``stop_at_outputs`` (native: step exactly to
        every output time instead of interpolating, so that the reported states satisfy the
        constraints to the Newton tolerance). ``atol`` may be a scalar, one value per
        (q, q') or, for GGL, one per (q, q', lambda, mu). ``events``: enable root finding.
        """
        t = output_times(t)
        if q0 is None:
            raise LagcodegenError("q0 is required")
        p = self.parameter_vector(params)
        rtol = check_finite(rtol, "rtol")
        y0 = self.consistent_initial_state(float(t[0]), q0, v0, p, initial=initial, ic_tol=ic_tol)
        try:
            self.kkt(t[0], y0, p)
        except SingularMassMatrixError as exc:
            raise SingularMassMatrixError(f"at the initial state: {exc}", t=float(t[0])) from None
        roots = bool(events) and len(self.info.events) > 0
        if backend not in ("native", "sksundae"):
            raise LagcodegenError(f"backend must be 'native' or 'sksundae', got {backend!r}")
        if self.formulation == "index1":
            alpha, beta = self.baumgarte if baumgarte is None else (check_finite(x, "baumgarte") for x in baumgarte)
            projection = self.projection if projection is None else bool(projection)
            if method is None:
                method = "bdf" if projection else "adams"
            if method not in METHODS:
                raise LagcodegenError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
            if projection and method != "bdf":
                raise LagcodegenError("projection onto the constraints (CVodeSetProjFn) needs method='bdf': "
                                      "CVODE supports projection with BDF only")
            atol_arr = _atol(atol, 2 * self.n)
            if backend == "native":
                res = self._solve_cvc(t, y0, p, method, rtol, atol_arr, float(alpha), float(beta), projection,
                                      proj_tol, proj_maxit, roots, max_events, max_steps, first_step, max_step,
                                      min_step, max_order)
            else:
                if projection:
                    raise LagcodegenError("the sksundae backend has no projection (scikit-sundae does not expose "
                                          "CVodeSetProjFn): use backend='native'")
                res = self._solve_sk_cvode(t, y0, p, method, rtol, atol_arr, float(alpha), float(beta), roots,
                                           max_steps, first_step, max_step, min_step, max_order)
            res.stats.update(alpha=float(alpha), beta=float(beta), projection=projection)
        else:
            if method not in (None, "bdf"):
                raise LagcodegenError("IDA integrates with BDF only (method='bdf')")
            method = "bdf"
            if jacobian is None:
                jacobian = self.info.ggl_jac
            if jacobian and not self.info.ggl_jac:
                raise LagcodegenError("jacobian=True but the residual Jacobian was not generated "
                                      "(compile_constrained(..., jacobian=False))")
            yy0, yp0 = self._ggl_initial(t[0], y0, p)
            atol_arr = _atol(atol, self.info.ng, 2 * self.n)
            if np.asarray(atol).size != self.info.ng:  # lambda, mu: see ALGEBRAIC_ATOL
                atol_arr[2 * self.n:] = ALGEBRAIC_ATOL if alg_atol is None else check_finite(alg_atol, "alg_atol")
            if backend == "native":
                res = self._solve_ida(t, yy0, yp0, p, rtol, atol_arr, bool(suppress_alg), bool(jacobian), roots,
                                      max_events, max_steps, first_step, max_step, min_step, max_order,
                                      bool(stop_at_outputs))
            else:
                res = self._solve_sk_ida(t, yy0, yp0, p, rtol, atol_arr, bool(jacobian), roots, max_steps,
                                         first_step, max_step, min_step, max_order)
        res.parameters = dict(zip(self.param_names, p))
        res.n_coordinates = self.n
        res.formulation = self.formulation
        if raise_on_error and not res.success:
            cls = SingularMassMatrixError if res.stats.get("model_error") == ERR_SINGULAR else SolverError
            t_end = res.stats.get("t_reached", res.t[-1] if res.t.size else t[0])
            raise cls(res.message, t=t_end, flag=res.status, result=res)
        return res

    # ------------------------------------------------------------------ index 1, native
    def _events_struct(self, ny: int, max_events: int, roots: bool):
        ffi, pre = self.ffi, self.info.prefix
        if not roots:
            return ffi.NULL, None
        keep = dict(t=np.full(max_events, np.nan), y=np.full((max_events, ny), np.nan),
                    which=np.zeros(max_events, dtype=np.intc), direction=np.zeros(max_events, dtype=np.intc),
                    rootdir=np.array([e.direction for e in self.info.events], dtype=np.intc),
                    terminal=np.array([1 if e.terminal else 0 for e in self.info.events], dtype=np.intc))
        ev = ffi.new(f"{pre}_events *")
        ev.max_events = max_events
        ev.t = ffi.from_buffer("double[]", keep["t"])
        ev.y = ffi.from_buffer("double[]", keep["y"])
        ev.which = ffi.from_buffer("int[]", keep["which"])
        ev.direction = ffi.from_buffer("int[]", keep["direction"])
        ev.rootdir = ffi.from_buffer("int[]", keep["rootdir"])
        ev.terminal = ffi.from_buffer("int[]", keep["terminal"])
        return ev, keep

    def _collect_events(self, ev, keep, ny) -> tuple[list[EventRecord], bool]:
        if keep is None:
            return [], False
        count = min(int(ev.n_events), len(keep["t"]))
        recs = records(self.info.events, keep["t"][:count], keep["y"][:count], keep["which"][:count],
                       keep["direction"][:count], self.state_names, 2 * self.n)
        return recs, bool(ev.terminated)

    def _finish(self, t, yout, out, done, recs, terminated, p, lam_event=None):
        """Trim the arrays and append the terminal event's row."""
        tt, yy, oo = t[:done].copy(), yout[:done].copy(), out[:done].copy()
        if terminated and recs:
            rec = recs[-1]
            if rec.t > tt[-1]:
                lam = None if lam_event is None else lam_event
                try:
                    o = self.outputs(rec.t, rec.y, p, lam=lam)
                except LagcodegenError:
                    o = np.full(oo.shape[1], np.nan)
                tt = np.append(tt, rec.t)
                yy = np.vstack([yy, rec.y[None, :]])
                oo = np.vstack([oo, np.resize(o, (1, oo.shape[1]))])
        return tt, yy, oo

    def _solve_cvc(self, t, y0, p, method, rtol, atol, alpha, beta, projection, proj_tol, proj_maxit, roots,
                   max_events, max_steps, first_step, max_step, min_step, max_order) -> Result:
        ffi, lib, pre = self.ffi, self.lib, self.info.prefix
        ny, nt, nout = 2 * self.n, t.size, len(self.info.output_names)
        yout = np.full((nt, ny), np.nan)
        out = np.full((nt, max(nout, 1)), np.nan)
        opt = ffi.new(f"{pre}_cvc_options *")
        st = ffi.new(f"{pre}_cvc_stats *")
        opt.method = METHODS[method]
        opt.rtol = rtol
        opt.atol = float(atol[0])
        atol_c = ffi.from_buffer("double[]", atol) if np.any(atol != atol[0]) else ffi.NULL
        opt.atol_vec = atol_c
        opt.max_steps = int(max_steps)
        opt.first_step = first_step
        opt.max_step = max_step
        opt.min_step = min_step
        opt.max_order = max_order
        opt.alpha = alpha
        opt.beta = beta
        opt.projection = int(projection)
        opt.proj_tol = proj_tol
        opt.proj_maxit = proj_maxit
        opt.proj_err = 1
        opt.roots = int(roots)
        ev, keep = self._events_struct(ny, max_events, roots)
        start = time.perf_counter()
        flag = getattr(lib, f"{pre}_cvc_solve")(self._ptr(p), ffi.from_buffer("double[]", y0), nt,
                                                ffi.from_buffer("double[]", t), ffi.from_buffer("double[]", yout),
                                                ffi.from_buffer("double[]", out), opt, st, ev)
        wall = time.perf_counter() - start
        recs, terminated = self._collect_events(ev, keep, ny)
        tt, yy, oo = self._finish(t, yout, out, st.nt_done, recs, terminated, p)
        stats = dict(steps=st.nsteps, rhs_evals=st.nrhs + st.nrhs_dq, rhs_evals_dq=st.nrhs_dq, jac_evals=st.njac,
                     lin_setups=st.nlinsetups, err_test_fails=st.netfails, nonlin_iters=st.nniters,
                     nonlin_conv_fails=st.nncfails, projections=st.nproj, projection_fails=st.nprojfails,
                     root_evals=st.ngevals, t_reached=st.t_reached, h_last=st.h_last, model_error=st.model_error,
                     wall_time=wall)
        detail = ffi.string(st.message).decode(errors="replace")
        res = Result(t=tt, y=yy, state_names=list(self.state_names),
                     outputs={k: oo[:, i].copy() for i, k in enumerate(self.info.output_names)}, stats=stats,
                     status=int(flag), message=_message(flag, st.model_error, detail, _CV_TEXT, "CVODE"),
                     backend="native", method=method)
        res.events = recs
        return res

    # ------------------------------------------------------------------ index 1, scikit-sundae
    def _solve_sk_cvode(self, t, y0, p, method, rtol, atol, alpha, beta, roots, max_steps, first_step,
                        max_step, min_step, max_order) -> Result:
        from sksundae.cvode import CVODE

        ffi, ny = self.ffi, 2 * self.n
        pp = self._ptr(p)
        crhs = self._crhs
        state = {"model_error": 0, "t": float(t[0])}

        def rhsfn(tt, y, yp):
            rc = crhs(tt, ffi.from_buffer("double[]", y), pp, alpha, beta,
                      ffi.from_buffer("double[]", yp, require_writable=True))
            if rc:
                if rc == ERR_SINGULAR:
                    state["model_error"], state["t"] = rc, tt
                yp[:] = np.nan

        options = dict(method="Adams" if method == "adams" else "BDF", rtol=rtol,
                       atol=atol if np.any(atol != atol[0]) else float(atol[0]), max_num_steps=max_steps,
                       first_step=first_step, max_step=max_step, min_step=min_step)
        if max_order:
            options["max_order"] = max_order
        if roots:
            options.update(self._sk_events(lambda tt, y: (y, None), p))
        start = time.perf_counter()
        soln = CVODE(rhsfn, **options).solve(t, y0)
        wall = time.perf_counter() - start
        return self._sk_result(soln, t, ny, p, state, wall, method, ny)

    def _sk_events(self, split, p, dae: bool = False):
        roots_c, ffi = self._roots, self.ffi
        pp = self._ptr(p)
        evs = self.info.events

        def fill(tt, y, ev_out):
            yv, lam = split(tt, y)
            lp = ffi.NULL if lam is None else ffi.from_buffer("double[]", lam)
            rc = roots_c(tt, ffi.from_buffer("double[]", yv), lp, pp,
                         ffi.from_buffer("double[]", ev_out, require_writable=True))
            if rc:
                ev_out[:] = np.nan

        if dae:
            def eventsfn(tt, y, yp, events):
                fill(tt, y, events)
        else:
            def eventsfn(tt, y, events):
                fill(tt, y, events)

        eventsfn.terminal = [bool(e.terminal) for e in evs]
        eventsfn.direction = [int(e.direction) for e in evs]
        return {"eventsfn": eventsfn, "num_events": len(evs)}

    def _sk_result(self, soln, t, ny, p, state, wall, method, ny_state, lam_slice=None) -> Result:
        done = len(soln.t)
        y = np.asarray(soln.y, dtype=float).reshape(done, -1)
        nout = len(self.info.output_names)
        outs = np.full((done, nout), np.nan)
        for k in range(done):
            lam = None if lam_slice is None else y[k, lam_slice]
            try:
                outs[k] = self.outputs(soln.t[k], y[k, :ny], p, lam=lam)
            except LagcodegenError:
                break
        recs = []
        if getattr(soln, "t_events", None) is not None:
            for k, te in enumerate(np.atleast_1d(soln.t_events)):
                info = np.atleast_2d(soln.i_events)[k]
                yk = np.atleast_2d(soln.y_events)[k]
                for i in np.flatnonzero(info):
                    ev = self.info.events[i]
                    recs.append(EventRecord(ev.name, int(i), float(te), np.array(yk[:ny], dtype=float),
                                            int(np.sign(info[i])), ev.terminal, list(self.state_names)))
        status = int(getattr(soln, "status", 0))
        stats = dict(steps=None, rhs_evals=int(getattr(soln, "nfev", -1)), jac_evals=int(getattr(soln, "njev", -1)),
                     t_reached=float(soln.t[-1]) if done else float(t[0]), model_error=state["model_error"],
                     wall_time=wall)
        message = str(getattr(soln, "message", ""))
        if status < 0 or not getattr(soln, "success", True):
            status = status if status < 0 else -3
            message = _message(status, state["model_error"], message, _CV_TEXT, "scikit-sundae")
            if state["model_error"]:
                stats["t_reached"] = state["t"]
        res = Result(t=np.asarray(soln.t, dtype=float), y=y[:, :ny].copy(), state_names=list(self.state_names),
                     outputs={k: outs[:, i] for i, k in enumerate(self.info.output_names)}, stats=stats,
                     status=status if status < 0 else 0, message=message if status < 0 else "success",
                     backend="sksundae", method=method)
        res.events = recs
        return res

    # ------------------------------------------------------------------ GGL
    def _ggl_initial(self, t0, y0, p):
        """yy0 = (q, v, lambda, mu = 0), yp0 = (v, q'', 0, 0) from the augmented system."""
        acc, lam = self.kkt(t0, y0, p)
        n, J, JH = self.n, self.info.J, self.info.JH
        yy0 = np.concatenate([y0, lam, np.zeros(JH)])
        yp0 = np.concatenate([y0[n:], acc, np.zeros(J + JH)])
        return yy0, yp0

    def ggl_residual(self, t, yy, yp, params=None) -> np.ndarray:
        """The GGL residual at (t, yy, yp)."""
        p = self._p(params)
        rr = np.empty(self.info.ng)
        rc = self._ggl_res(float(t), self._ptr(np.ascontiguousarray(yy, float)),
                           self._ptr(np.ascontiguousarray(yp, float)), self._ptr(p), self._ptr(rr))
        self._check(rc, t, "GGL residual")
        return rr

    def ggl_jacobian(self, t, cj, yy, yp, params=None) -> np.ndarray:
        """dF/dyy + cj dF/dyp of the GGL residual (ng x ng)."""
        p = self._p(params)
        ng = self.info.ng
        J = np.empty((ng, ng), order="F")
        rc = self._ggl_jac(float(t), float(cj), self._ptr(np.ascontiguousarray(yy, float)),
                           self._ptr(np.ascontiguousarray(yp, float)), self._ptr(p), self.ffi.from_buffer("double[]", J.T))
        self._check(rc, t, "GGL Jacobian")
        return J

    def _ggl_outputs_extra(self, yy: np.ndarray) -> dict:
        n, J, JH = self.n, self.info.J, self.info.JH
        return {f"mu_{k}": yy[:, 2 * n + J + k].copy() for k in range(JH)}

    def _solve_ida(self, t, yy0, yp0, p, rtol, atol, suppress_alg, jacobian, roots, max_events, max_steps,
                   first_step, max_step, min_step, max_order, stop_at_outputs) -> Result:
        ffi, lib, pre = self.ffi, self.lib, self.info.prefix
        ng, nt, nout, n = self.info.ng, t.size, len(self.info.output_names), self.n
        yout = np.full((nt, ng), np.nan)
        out = np.full((nt, max(nout, 1)), np.nan)
        opt = ffi.new(f"{pre}_ida_options *")
        st = ffi.new(f"{pre}_ida_stats *")
        opt.rtol = rtol
        opt.atol = float(atol[0])
        opt.atol_vec = ffi.from_buffer("double[]", atol) if np.any(atol != atol[0]) else ffi.NULL
        opt.max_steps = int(max_steps)
        opt.first_step = first_step
        opt.max_step = max_step
        opt.min_step = min_step
        opt.max_order = max_order
        opt.suppress_alg = int(suppress_alg)
        opt.jacobian = int(jacobian)
        opt.calc_ic = 1
        opt.ic_alg_atol = SKSUNDAE_ALGEBRAIC_ATOL
        opt.roots = int(roots)
        opt.stop_at_outputs = int(stop_at_outputs)
        ev, keep = self._events_struct(ng, max_events, roots)
        start = time.perf_counter()
        flag = getattr(lib, f"{pre}_ida_solve")(self._ptr(p), ffi.from_buffer("double[]", yy0),
                                                ffi.from_buffer("double[]", yp0), nt, ffi.from_buffer("double[]", t),
                                                ffi.from_buffer("double[]", yout), ffi.from_buffer("double[]", out),
                                                opt, st, ev)
        wall = time.perf_counter() - start
        recs, terminated = [], False
        if keep is not None:
            count = min(int(ev.n_events), max_events)
            recs = records(self.info.events, keep["t"][:count], keep["y"][:count], keep["which"][:count],
                           keep["direction"][:count], self.state_names, 2 * n)
            terminated = bool(ev.terminated)
        done = st.nt_done
        tt, yy, oo = t[:done].copy(), yout[:done].copy(), out[:done].copy()
        if terminated and recs and keep is not None:
            count = min(int(ev.n_events), max_events)
            row = keep["y"][count - 1]
            if recs[-1].t > (tt[-1] if tt.size else -np.inf):
                try:
                    o = self.outputs(recs[-1].t, row[: 2 * n], p, lam=row[2 * n: 2 * n + self.info.J])
                except LagcodegenError:
                    o = np.full(oo.shape[1], np.nan)
                tt = np.append(tt, recs[-1].t)
                yy = np.vstack([yy, row[None, :]])
                oo = np.vstack([oo, np.resize(o, (1, oo.shape[1]))])
        stats = dict(steps=st.nsteps, rhs_evals=st.nres + st.nres_dq, res_evals=st.nres, res_evals_dq=st.nres_dq,
                     jac_evals=st.njac, lin_setups=st.nlinsetups, err_test_fails=st.netfails,
                     nonlin_iters=st.nniters, nonlin_conv_fails=st.nncfails, backtracks=st.nbacktracks,
                     root_evals=st.ngevals, t_reached=st.t_reached, h_last=st.h_last, model_error=st.model_error,
                     ic_flag=st.ic_flag, suppress_alg=suppress_alg, wall_time=wall)
        detail = ffi.string(st.message).decode(errors="replace")
        outputs = {k: oo[:, i].copy() for i, k in enumerate(self.info.output_names)}
        outputs.update(self._ggl_outputs_extra(yy))
        res = Result(t=tt, y=yy[:, : 2 * n].copy(), state_names=list(self.state_names), outputs=outputs,
                     stats=stats, status=int(flag), backend="native", method="bdf",
                     message=("IDACalcIC found no consistent lambda, y': " if st.ic_flag < 0 else "")
                     + _message(flag, st.model_error, detail, _IDA_TEXT, "IDA"))
        res.events = recs
        return res

    def _solve_sk_ida(self, t, yy0, yp0, p, rtol, atol, jacobian, roots, max_steps, first_step, max_step,
                      min_step, max_order) -> Result:
        from sksundae.ida import IDA

        ffi, n, ng, J = self.ffi, self.n, self.info.ng, self.info.J
        pp = self._ptr(p)
        cres, cjac = self._ggl_res, self._ggl_jac
        state = {"model_error": 0, "t": float(t[0])}
        jbuf = np.empty((ng, ng), order="F")

        def resfn(tt, y, yp, res):
            rc = cres(tt, ffi.from_buffer("double[]", y), ffi.from_buffer("double[]", yp), pp,
                      ffi.from_buffer("double[]", res, require_writable=True))
            if rc:
                res[:] = np.nan

        def jacfn(tt, y, yp, res, cj, JJ):
            rc = cjac(tt, cj, ffi.from_buffer("double[]", y), ffi.from_buffer("double[]", yp), pp,
                      ffi.from_buffer("double[]", jbuf.T))
            if rc:
                jbuf[:] = np.nan
            JJ[:, :] = jbuf

        # scikit-sundae never calls IDASetSuppressAlg: a huge atol keeps lambda, mu out of the error test.
        atol = atol.copy()
        atol[2 * n:] = np.maximum(atol[2 * n:], SKSUNDAE_ALGEBRAIC_ATOL)
        options = dict(rtol=rtol, atol=atol, algebraic_idx=list(range(2 * n, ng)), calc_initcond="yp0",
                       calc_init_dt=float(t[1] - t[0]), max_num_steps=max_steps, first_step=first_step,
                       max_step=max_step, min_step=min_step)
        if max_order:
            options["max_order"] = max_order
        if jacobian:
            options["jacfn"] = jacfn
        if roots:
            options.update(self._sk_events(lambda tt, y: (np.ascontiguousarray(y[: 2 * n]),
                                                          np.ascontiguousarray(y[2 * n: 2 * n + J])), p, dae=True))
        start = time.perf_counter()
        soln = IDA(resfn, **options).solve(t, yy0, yp0)
        wall = time.perf_counter() - start
        res = self._sk_result(soln, t, 2 * n, p, state, wall, "bdf", ng, lam_slice=slice(2 * n, 2 * n + J))
        yfull = np.asarray(soln.y, dtype=float).reshape(len(soln.t), -1)
        res.outputs.update(self._ggl_outputs_extra(yfull))
        res.stats["algebraic_atol"] = SKSUNDAE_ALGEBRAIC_ATOL
        if res.status < 0 and not res.message.startswith("IDA"):
            res.message = _message(res.status, state["model_error"], str(getattr(soln, "message", "")),
                                   _IDA_TEXT, "IDA")
        return res


def _norm(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.max(np.abs(x))) if x.size else 0.0


def _atol(atol, size: int, n_diff: int | None = None) -> np.ndarray:
    """Absolute tolerances: a scalar or one per state (or per differential state, the rest copied)."""
    arr = np.asarray(atol, dtype=float).ravel()
    if arr.size == 1:
        out = np.full(size, float(arr[0]))
    elif n_diff is not None and arr.size == n_diff:
        out = np.concatenate([arr, np.full(size - n_diff, float(np.min(arr)))])
    elif arr.size == size:
        out = arr.copy()
    else:
        raise LagcodegenError(f"atol has {arr.size} values, expected 1 or {n_diff or size}")
    if not np.all(np.isfinite(out)) or np.any(out < 0):
        raise LagcodegenError("tolerances must be finite and non-negative")
    return out


# ---------------------------------------------------------------------- minimal coordinates
def solve_constraints(system: ConstrainedSystem, eliminate: Sequence | None = None):
    """Solve the holonomic constraints symbolically for J coordinates (sympy).

    Returns (eliminated coordinate symbols, list of solution branches {q_e: expr in the
    remaining q, t}). Tries ``eliminate`` if given, else every subset of J coordinates, the
    last coordinates first. Raises ModelError when sympy solves none.
    """
    model = system.model
    if system.nonholonomic:
        raise ModelError("minimal coordinates need holonomic constraints only: nonholonomic constraints "
                         f"({system.n_nonholonomic}) cannot be eliminated; use formulation 'index1' or 'ggl'")
    J = system.n_holonomic
    if J == 0:
        raise ModelError("minimal coordinates: there are no holonomic constraints to eliminate")
    if eliminate is not None:
        subset = tuple(model.coords[model.index(q)] for q in eliminate)
        if len(subset) != J:
            raise ModelError(f"eliminate: {len(subset)} coordinate(s) given, but there are {J} holonomic constraints")
        candidates = [subset]
    else:
        candidates = list(itertools.combinations(list(reversed(model.coords)), J))
    tried = []
    for subset in candidates:
        tried.append("(" + ", ".join(q.name for q in subset) + ")")
        try:
            sols = sp.solve(list(system.holonomic), list(subset), dict=True)
        except (NotImplementedError, ValueError, TypeError):
            continue
        good = []
        for sol in sols:
            if set(sol) != set(subset):
                continue
            if any(expr.free_symbols & set(subset) for expr in sol.values()):
                continue
            good.append({q: sp.sympify(sol[q]) for q in subset})
        if good:
            return list(subset), good
    raise ModelError("minimal coordinates: sympy cannot solve the holonomic constraints "
                     f"{', '.join(f'{f} = 0' for f in system.holonomic)} for any set of {J} coordinate(s) "
                     f"(tried {', '.join(tried)}); use formulation 'index1' or 'ggl'")


def reduced_model(system: ConstrainedSystem, solution: Mapping, name: str | None = None) -> Model:
    """A new Model in the remaining coordinates, with the solved ones substituted everywhere.

    Eliminated velocities become d/dt of their solutions; a generalized force Q*_e on an
    eliminated coordinate is mapped by virtual work (Q*_r += Q*_e dq_e/dq_r). The eliminated
    coordinates and velocities are added as outputs ``<q_e>`` and ``<q_e>_dot``.
    """
    old = system.model
    new = Model(name or f"{old.name}_min")
    keep = [q for q in old.coords if q not in solution]
    new.coordinates([q.name for q in keep])
    for sym_, val in old.params.items():
        new.parameter(sym_.name, val)
    sub = dict(solution)
    for qe, expr in solution.items():
        vel = sp.diff(expr, old.t) + sum((sp.diff(expr, q) * old.dot(q) for q in keep), sp.Integer(0))
        sub[old.dot(qe)] = vel

    def S(e):
        return sp.sympify(e).xreplace(sub)

    def V(vec):
        return [S(c) for c in vec]

    from .model import Particle, PlanarBody, RigidBody
    body_points = set()
    for body in old.bodies:
        body_points.add(body.point.name)
        if isinstance(body, Particle):
            new.particle(body.name, S(body.mass), V(body.point.position))
        elif isinstance(body, PlanarBody):
            new.planar_body(body.name, S(body.mass), S(body.inertia), V(body.point.position), S(body.angle))
        elif isinstance(body, RigidBody):
            new.rigid_body(body.name, S(body.mass), body.inertia.applyfunc(S), V(body.point.position),
                           body.orientation.applyfunc(S))
    for pname, pt in old.points.items():
        if pname not in body_points:
            new.point(pname, V(pt.position))
    for label, T in old.kinetic_terms:
        new.kinetic_energy(S(T), label)
    for label, Vt in old.potential_terms:
        new.potential_energy(S(Vt), label)
    for label, U in old.generalized_potential_terms:
        new.generalized_potential(S(U), label)
    for label, D in old.dissipation_terms:
        new.dissipation(S(D), label)
    for label, pt, F in old.cartesian_forces:
        target = pt.name if pt.name in new.points else V(pt.position)
        new.force(target, V(F), label)
    for label, i, Q in old.generalized_forces:
        qi = old.coords[i]
        if qi in solution:
            for qr in keep:
                factor = sp.diff(solution[qi], qr)
                if factor != 0:
                    new.generalized_force(qr, S(Q) * factor, f"{label} (via {qi.name})")
        else:
            new.generalized_force(qi, S(Q), label)
    if old.gravity_spec is not None:
        g, up = old.gravity_spec
        new.gravity_spec = (S(g), up)
    for oname, expr in old.outputs.items():
        new.output(oname, S(expr))
    for qe, expr in solution.items():
        if qe.name not in new.outputs:
            new.output(qe.name, expr)
        if f"{qe.name}_dot" not in new.outputs:
            new.output(f"{qe.name}_dot", sub[old.dot(qe)])
    return new


class MinimalSimulation(_Base):
    """Constrained system integrated in minimal coordinates (holonomic constraints eliminated).

    The solution branch (e.g. y = -sqrt(l^2 - x^2) or +sqrt) is chosen at simulate time from q0;
    each branch is compiled once. Multipliers are not available in this formulation.
    """

    formulation = "minimal"

    def __init__(self, system: ConstrainedSystem, outputs=None, events=(), runtime_parameters=None, values=None,
                 prefix=None, eliminate=None, verbose=False):
        self.system = system
        if list(events) or system.inequalities:
            raise ModelError("minimal coordinates: events and inequality constraints need formulation 'index1' "
                             "or 'ggl' (the plain CVODE driver has no root finding)")
        self.eliminated, self.branches = solve_constraints(system, eliminate)
        self.remaining = [q for q in system.model.coords if q not in self.eliminated]
        outputs = ("energy", "residuals") if outputs is None else tuple(outputs)
        self._requested = outputs
        names = []
        self._python_outputs = []
        for item in outputs:
            if item in ("lambda", "constraint_forces") or item.startswith("lambda_") or item.startswith("R_"):
                raise ModelError(f"output {item!r}: minimal coordinates have no Lagrange multipliers "
                                 "(use formulation 'index1' or 'ggl')")
            if item in ("residuals", "inequalities") or item.startswith("g_") or item.startswith("gdot_"):
                self._python_outputs.append(item)
            else:
                names.append(item)
        self._model_outputs = names
        self._runtime_parameters = runtime_parameters
        self._values = dict(values or {})
        self._prefix = prefix
        self._verbose = verbose
        self._compiled: dict[int, CompiledModel] = {}
        self._reduced: dict[int, Model] = {}
        model = system.model
        folded_names = [s.name for s in model.params]
        if runtime_parameters is not None:
            folded_names = [nm for nm in folded_names if nm not in set(runtime_parameters)]
        else:
            folded_names = []
        defaults = {s.name: v for s, v in model.params.items()}
        self._folded = {nm: float(self._values.get(nm, defaults[nm])) for nm in folded_names}
        # numerical constraint residuals for the outputs g_j, gdot_j (from the reconstructed full state)
        args = list(model.coords) + list(model.speeds) + [model.t] + list(model.params)
        self._args = args
        self._g_fn = sp.lambdify(args, list(system.holonomic), modules="numpy")
        self._s_fn = sp.lambdify(args, list(system.velocity_residuals()), modules="numpy")

    @property
    def state_names(self) -> list[str]:
        return [q.name for q in self.remaining] + [f"{q.name}_dot" for q in self.remaining]

    @property
    def param_names(self) -> list[str]:
        names = [s.name for s in self.system.model.params]
        return names if self._runtime_parameters is None else list(self._runtime_parameters)

    def compiled_branch(self, b: int) -> CompiledModel:
        if b not in self._compiled:
            red = reduced_model(self.system, self.branches[b], name=f"{self.system.model.name}_min{b}")
            scene = Scene(derive(red), outputs=[*self._model_outputs, *[f"{q.name}" for q in self.eliminated],
                                                 *[f"{q.name}_dot" for q in self.eliminated]],
                          runtime_parameters=self._runtime_parameters, values=self._values,
                          prefix=self._prefix and f"{self._prefix}_b{b}")
            self._reduced[b] = red
            self._compiled[b] = build(generate_c(scene), native=True, verbose=self._verbose)
        return self._compiled[b]

    def _branch_for(self, q: np.ndarray, t0: float, vals: dict, tol: float) -> int:
        model = self.system.model
        subs = {**{s: q[i] for i, s in enumerate(model.coords)}, model.t: t0,
                **{s: vals[s.name] for s in model.params}}
        best, err = None, np.inf
        for b, sol in enumerate(self.branches):
            try:
                e = max(abs(complex(sp.sympify(sol[qe]).xreplace(subs).evalf()) - q[model.index(qe)])
                        for qe in self.eliminated)
            except (TypeError, ValueError):
                continue
            if e < err:
                best, err = b, e
        if best is None or err > tol * (1 + float(np.max(np.abs(q)))):
            raise ModelError(f"minimal coordinates: no solution branch of the constraints matches q0 "
                             f"(closest differs by {err:.3g}); inconsistent initial conditions")
        return best

    def simulate(self, t, q0=None, v0=None, params: Mapping | None = None, rtol: float = 1e-8, atol=1e-10,
                 backend: str = "native", method: str | None = None, initial: str = "check", ic_tol: float = 1e-8,
                 raise_on_error: bool = True, **kwargs) -> Result:
        """Integrate in the remaining coordinates; q0/v0 are given for all n coordinates.

        ``initial="check"`` requires them to satisfy the constraints (within ``ic_tol``);
        ``"project"`` keeps the remaining coordinates and velocities and recomputes the
        eliminated ones. Other keyword arguments go to :func:`lagcodegen.solve.simulate`.
        """
        for key in ("baumgarte", "projection", "suppress_alg", "events"):
            kwargs.pop(key, None)
        t = output_times(t)
        model = self.system.model
        names = [q.name for q in model.coords]
        q = state_vector(q0, names, "q0")
        v = state_vector(v0, names, "v0")
        defaults = {s.name: v_ for s, v_ in model.params.items()}
        vals = {**defaults, **self._values}
        for k, val in (params or {}).items():
            if k not in self.param_names:
                raise LagcodegenError(f"{k!r} is not a run-time parameter (run-time parameters: "
                                      f"{', '.join(self.param_names) or 'none'})")
            vals[k] = check_finite(val, f"parameter {k!r}")
        if initial == "check":
            self.system.check_initial(q, v, vals, t0=float(t[0]), tol=ic_tol)
        elif initial not in ("project", "none"):
            raise LagcodegenError(f"initial must be 'check', 'project' or 'none', got {initial!r}")
        tol = ic_tol if initial == "check" else np.inf
        b = self._branch_for(q, float(t[0]), vals, tol)
        cm = self.compiled_branch(b)
        idx = [model.index(qr) for qr in self.remaining]
        run_params = {k: vals[k] for k in cm.param_names}
        start = time.perf_counter()
        res = cm.simulate(t, q0=q[idx], v0=v[idx], params=run_params, rtol=rtol, atol=atol, backend=backend,
                          method=method or "adams", raise_on_error=raise_on_error, **kwargs)
        res.stats["wall_time"] = time.perf_counter() - start
        res.stats["branch"] = b
        self._add_residuals(res, vals)
        res.formulation = "minimal"
        res.events = []
        return res

    def full_state(self, res: Result) -> tuple[np.ndarray, np.ndarray]:
        """(q, q') of all n coordinates along a result (eliminated ones from the outputs)."""
        model = self.system.model
        q = np.column_stack([res[c.name] for c in model.coords])
        v = np.column_stack([res[f"{c.name}_dot"] for c in model.coords])
        return q, v

    def _add_residuals(self, res: Result, vals: dict) -> None:
        want = self._python_outputs
        if not want:
            return
        model = self.system.model
        q, v = self.full_state(res)
        args = [q[:, i] for i in range(model.n)] + [v[:, i] for i in range(model.n)] + [res.t]
        args += [np.full_like(res.t, vals[s.name]) for s in model.params]
        JH, J = self.system.n_holonomic, self.system.J
        g = np.atleast_2d(np.array([np.broadcast_to(x, res.t.shape) for x in self._g_fn(*args)], dtype=float))
        s = np.atleast_2d(np.array([np.broadcast_to(x, res.t.shape) for x in self._s_fn(*args)], dtype=float))
        extra = {}
        for j in range(JH):
            extra[f"g_{j}"] = g[j]
        for j in range(J):
            extra[f"gdot_{j}"] = s[j]
        for item in want:
            if item == "residuals":
                res.outputs.update(extra)
            elif item in extra:
                res.outputs[item] = extra[item]
