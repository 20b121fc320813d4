"""Constrained dynamics in generated C or Fortran: index-1 on CVODE, GGL on IDA, minimal coordinates.

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

``lang="fortran"`` (index1, ggl) generates the model functions as Fortran 2008 modules bound
to the C names (:mod:`lagcodegen.fortran`); the native drivers stay C and call them through
the same header, so results and solver statistics are the C version's.
"""

from __future__ import annotations

import time
from typing import Mapping

import numpy as np

from ..errors import LagcodegenError, ModelError, SingularMassMatrixError, SolverError
from ..formulation.constrained import ConstrainedCodeInfo
from ..model.events import Event, EventRecord, records
from ..result import Result
from ..theory.constraints import ConstrainedSystem, dependent_rows, rank_tolerance
from ..util import check_finite, output_times, state_vector
from .base import CVODE_FLAG_TEXT
from .compiled import CompiledModel

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
            A = ev["A"]
            if np.linalg.matrix_rank(A, tol=rank_tolerance(A)) < self.system.J:
                raise ModelError("singular constraint Jacobian at the initial state: cannot project; "
                                 + dependent_rows(A))
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
