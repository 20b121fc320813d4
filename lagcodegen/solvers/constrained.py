"""Constrained dynamics in generated C or Fortran: index-1 on CVODE, GGL on IDA, minimal coordinates.

:func:`compile_constrained` turns a :class:`~lagcodegen.constraints.ConstrainedSystem` into
compiled code with one of three formulations of the equations with multipliers (eq. 4.5)

    M q'' = F + A^T lambda,   A q' + A0 = 0   (eqs. 4.2, 4.3; f(q, t) = 0, eq. 4.1, for holonomic rows)

* ``"index1"``: differentiate every constraint to the acceleration level, A q'' = gamma, and
  solve the augmented (n+J) x (n+J) system [M A^T; A 0][q''; -lambda] = [F; gamma - stab]
  numerically in C (Schur complement of M by Cholesky, else dense LU with partial pivoting) at
  every right-hand-side call; integrate y = (q, q') with CVODE (difference-quotient Jacobian).
  Drift of f(q) and A q' + A0 is controlled by Baumgarte stabilization (f'' + 2 alpha f' +
  beta^2 f = 0 for holonomic rows, s' + alpha s = 0 for nonholonomic rows s = A q' + A0; by
  default alpha = beta = the natural rate of each run's initial state) and/or by projection onto the
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
the same function table, so results and solver statistics are the C version's.

The native drivers are model-independent and compiled once, into the runtime
(:func:`lagcodegen.build.runtime`): a model compiles only its own functions (model, ``<prefix>_dae.c``
and its table ``<prefix>_dae_table.c``, lcg_dae_model.h) into a library without Python.h, and
every function of it is called through that table, from the drivers and from Python alike.

One job: :class:`ConstrainedSimulation`, the Python face of a compiled constrained system (its
layout, its compiled functions, the consistent initial state, and the call of each formulation's
runner); the runners themselves are the solver families' (cvode, ida, sksundae, ensemble).
"""

from __future__ import annotations

import functools
import inspect
import math
from typing import Mapping

import numpy as np

from ..errors import LagcodegenError, ModelError, SingularMassMatrixError, SolverError
from ..formulation.constrained import ConstrainedCodeInfo
from ..model.events import Event
from ..result import Result
from ..theory.constraints import ConstrainedSystem, dependent_rows, rank_tolerance
from ..util import BAUMGARTE_AUTO, c_vector, check_baumgarte, check_finite, output_times, state_values, state_vector
from . import cvode, ida, sksundae
from .base import _DOUBLE, ERR_PROJECTION, ERR_SINGULAR, METHODS, NativeEvents, PreparedOptions, tolerances
from .compiled import CompiledModel
from .control import POLL_EVERY
from .ensemble import ensemble_constrained
from .ida import ALGEBRAIC_ATOL
from .options import merge

#: Kept under its earlier name: the tolerance of lambda, mu on scikit-sundae's IDA.
SKSUNDAE_ALGEBRAIC_ATOL = ALGEBRAIC_ATOL
#: ``initial`` of simulate() -> the mode of the runtime's ``lcg_dae_initial_state``.
_INITIAL_MODES = {"none": 0, "check": 1, "project": 2}
#: Events structs (with their buffers, max_events x NY values) kept for reuse per simulation and
#: value of max_events, at most; and the values of max_events kept at most.
_EVENT_POOL, _EVENT_POOL_KEYS = 2, 8

class _Base:
    """What every compiled constrained system offers: layout, parameters, initial-state checks."""

    system: ConstrainedSystem

    @property
    def n(self) -> int:
        """Number of coordinates."""
        return self.system.model.n

    def _effective_params(self, scene_defaults: dict, p_names: list, p: np.ndarray) -> dict:
        vals = dict(scene_defaults)
        vals.update(zip(p_names, (float(x) for x in p)))
        return vals


class ConstrainedSimulation(_Base):
    """A compiled constrained system (formulation ``index1`` or ``ggl``); call :meth:`simulate`."""

    def __init__(self, system: ConstrainedSystem, formulation: str, cm: CompiledModel, info: ConstrainedCodeInfo,
                 baumgarte: tuple[float, float] | str, projection: bool):
        self.system = system
        self.formulation = formulation
        self.compiled = cm
        self.info = info
        self.baumgarte = baumgarte
        self.projection = projection
        self.ffi, self.lib = cm.ffi, cm.lib  # the runtime module (its drivers and C types)
        table = cm.dae_table  # the model's constrained function table (lcg_dae_model.h)
        if table is None:
            raise LagcodegenError("ConstrainedSimulation needs constrained code built for the runtime's drivers "
                                  "(generate_constrained, then build with native=True)")
        self.table = table
        null, lib = self.ffi.NULL, self.lib
        # the generated functions (through the table), called by the runners of each solver family
        self.c_kkt = table.kkt
        self.c_crhs = table.crhs
        self.c_natural_rate = table.natural_rate
        self.c_residuals = table.residuals
        self.c_project = table.project
        self.c_outputs = table.coutputs
        self.c_roots = table.roots if table.roots != null else None
        self.c_ggl_res = table.ggl_res if table.ggl_res != null else None
        self.c_ggl_jac = table.ggl_jac if table.ggl_jac != null else None
        # the runtime's model-independent drivers applied to this model, their C types, and the
        # initial state in one call
        self.c_cvc_solve = functools.partial(lib.lcg_cvc_solve, table)
        self.c_ida_solve = functools.partial(lib.lcg_ida_solve, table) if self.c_ggl_res is not None else None
        self.c_initial_state = functools.partial(lib.lcg_dae_initial_state, table)
        self.cvc_options_type, self.cvc_stats_type = "lcg_cvc_options", "lcg_cvc_stats *"
        self.ida_options_type, self.ida_stats_type = "lcg_ida_options", "lcg_ida_stats *"
        self.cvc_ensemble_type, self.ida_ensemble_type, self.events_type = ("lcg_cvc_ensemble", "lcg_ida_ensemble",
                                                                            "lcg_events")
        # the drivers' options structs, kept across calls (one per distinct set of option values)
        self.cvc_options = PreparedOptions(self.ffi, self.cvc_options_type, *cvode.CVC_OPTIONS, proj_err=1,
                                           poll=cm.poll, poll_every=POLL_EVERY)
        self.ida_options = PreparedOptions(self.ffi, self.ida_options_type, *ida.IDA_OPTIONS, calc_ic=1,
                                           ic_alg_atol=ALGEBRAIC_ATOL, poll=cm.poll, poll_every=POLL_EVERY)
        # layout, fixed at compile time (read on every call)
        self._n = system.model.n
        self._state_names = list(cm.state_names[: 2 * self._n])
        self._coord_names = [q.name for q in system.model.coords]
        self._nineq = len(system.inequalities)
        self._ggl = formulation == "ggl"
        self._mu_names = [f"mu_{k}" for k in range(info.JH)]
        self._has_events = len(info.events) > 0
        self.n_out_columns = max(len(info.output_names), 1)  # columns of the drivers' output rows
        self._event_pool: dict = {}  # max_events -> NativeEvents structs free for reuse
        self._pair_times = None  # (key, array) of the last t = (t0, t1)
        self._ggl_atol = (None, None)  # (bytes of a scalar atol, GGL tolerances of every unknown) of the last call
        self.cvc_stats_pool: list = []  # the drivers' statistics structs free for reuse
        self.ida_stats_pool: list = []
        self._double_array = self.ffi.typeof("double[]")
        # the default parameters (read-only) and their C pointer, for runs without ``params``
        self._default_p = cm.parameter_vector(None)
        self._default_p.flags.writeable = False
        self._default_pc = self._ptr(self._default_p)
        self._default_parameters = dict(zip(self.param_names, self._default_p))  # Result.parameters

    # ------------------------------------------------------------------ layout
    @property
    def n(self) -> int:
        """Number of coordinates."""
        return self._n

    @property
    def state_names(self) -> list[str]:
        return list(self._state_names)

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
        return self.ffi.from_buffer(self._double_array, arr) if arr.size else self.ffi.NULL

    def _p(self, params):
        """Run-time parameters: an array of exactly np values, or a mapping by name (defaults)."""
        if params is None or isinstance(params, Mapping):
            return self.parameter_vector(params)
        return c_vector(params, len(self.param_names), "params", self.param_names)

    def c_params(self, p: np.ndarray):
        """``p`` as the C pointer the generated drivers take (NULL without run-time parameters)."""
        if p is self._default_p:
            return self._default_pc
        return self._ptr(p)

    def _y(self, y, size: int | None = None, what: str = "y") -> np.ndarray:
        names = self.state_names if size is None else None
        return c_vector(y, 2 * self.n if size is None else size, what, names)

    # ------------------------------------------------------------------ generated functions
    def kkt(self, t: float, y, params=None, alpha: float = 0.0, beta: float = 0.0):
        """(q'', lambda) from the augmented system at (t, y)."""
        y = self._y(y)
        p = self._p(params)
        acc, lam = np.empty(self.n), np.empty(max(self.info.J, 1))
        rc = self.c_kkt(float(t), self._ptr(y), self._ptr(p), float(alpha), float(beta), self._ptr(acc), self._ptr(lam))
        self._check(rc, t, "augmented system")
        return acc, lam[: self.info.J]

    def residuals(self, t: float, y, params=None):
        """(f(q, t) of the holonomic constraints, A q' + A0 of every constraint)."""
        y = self._y(y)
        p = self._p(params)
        g, s = np.empty(max(self.info.JH, 1)), np.empty(max(self.info.J, 1))
        rc = self.c_residuals(float(t), self._ptr(y), self._ptr(p), self._ptr(g), self._ptr(s))
        self._check(rc, t, "constraint residuals")
        return g[: self.info.JH], s[: self.info.J]

    def natural_rate(self, t: float, y, params=None) -> float:
        """The rate (1/time) of the system's fastest motion at (t, y): max(sqrt(max_i |dq''_i/dq_i|),
        max_i |dq''_i/dq'_i|), diagonal entries of the unstabilized index-1 Jacobian (forward
        differences in C); alpha = beta of ``baumgarte="auto"``. Unchanged when coordinates are
        rescaled; within 1.2x of the Jacobian's largest eigenvalue on benchmarks/bari.py's problems."""
        y = self._y(y)
        rate = self.ffi.new("double *")
        rc = self.c_natural_rate(float(t), self._ptr(y), self._ptr(self._p(params)), rate)
        self._check(rc, t, "natural rate")
        return rate[0]

    def _stabilization(self, baumgarte, projection: bool, t0: float, y0: np.ndarray, p: np.ndarray,
                       native: bool = True):
        """(alpha, beta) of an index-1 run: ``baumgarte`` (None: the compiled default) resolved;
        "auto" none with projection, else (-1, -1) for the native driver (which takes the natural
        rate of each run's initial state) or the rate at (t0, y0) (0 where it cannot be computed)."""
        stab = self.baumgarte if baumgarte is None else check_baumgarte(baumgarte)
        if stab != BAUMGARTE_AUTO:
            return stab
        if projection:
            return 0.0, 0.0
        if native:
            return -1.0, -1.0
        try:
            rate = self.natural_rate(t0, y0, p)
        except LagcodegenError:  # the run reports the model's error at its first step
            rate = 0.0
        return rate, rate

    def project(self, t: float, y, params=None, tol: float = 1e-14, maxit: int = 50) -> np.ndarray:
        """y projected onto f(q, t) = 0 (Gauss-Newton) and A q' + A0 = 0."""
        y = self._y(y)
        p = self._p(params)
        out = np.empty_like(y)
        rc = self.c_project(float(t), self._ptr(y), self._ptr(p), float(tol), int(maxit), self._ptr(out), self.ffi.NULL)
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
        y = self._y(y)
        p = self._p(params)
        out = np.empty(max(len(self.info.output_names), 1))
        lp = self.ffi.NULL if lam is None else self._ptr(self._y(lam, self.info.J, "lam"))
        rc = self.c_outputs(float(t), self._ptr(y), lp, self._ptr(p), self._ptr(out))
        self._check(rc, t, "outputs")
        return out[: len(self.info.output_names)]

    def roots(self, t: float, y, params=None, lam=None) -> np.ndarray:
        """Event functions at (t, y)."""
        y = self._y(y)
        if self.c_roots is None:
            return np.empty(0)
        p = self._p(params)
        out = np.empty(len(self.info.events))
        lp = self.ffi.NULL if lam is None else self._ptr(self._y(lam, self.info.J, "lam"))
        rc = self.c_roots(float(t), self._ptr(y), lp, self._ptr(p), self._ptr(out))
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
        y = np.concatenate([q, v])
        if initial == "none":
            return y
        if initial not in ("check", "project"):
            raise LagcodegenError(f"initial must be 'check', 'project' or 'none', got {initial!r}")
        if initial == "check":
            if not self._consistent(t0, y, p, ic_tol):
                # the symbolic check names what is wrong (rank, which constraint, by how much)
                self.system.check_initial(q, v, self._values(p), t0=t0, tol=ic_tol)
            return self.project(t0, y, p)
        # project: Gauss-Newton, then verify; a failure is explained by the symbolic rank test
        try:
            yp = self.project(t0, y, p)
        except ModelError:
            self._explain_rank(q, v, p, t0)
            raise
        g, s = self.residuals(t0, yp, p)
        if _norm(g) > ic_tol or _norm(s) > ic_tol:
            raise ModelError(f"cannot make the initial state consistent: after projection |f(q)| = {_norm(g):.3g}, "
                             f"|A q' + A0| = {_norm(s):.3g} (tolerance {ic_tol:.3g})")
        return yp

    def _values(self, p: np.ndarray) -> dict:
        return self._effective_params(self.info.folded, self.param_names, p)

    def _consistent(self, t0: float, y: np.ndarray, p: np.ndarray, tol: float) -> bool:
        """The initial-state check on the compiled functions (no sympy in the call): constraint
        residuals within ``tol``, inequalities not violated, the augmented matrix regular."""
        try:
            g, s = self.residuals(t0, y, p)
            if any(not abs(x) <= tol for x in g) or any(not abs(x) <= tol for x in s):
                return False
            n_ineq = len(self.system.inequalities)
            if n_ineq and any(not x >= -tol for x in self.roots(t0, y, p)[:n_ineq]):
                return False
            self.kkt(t0, y, p)
        except (SolverError, SingularMassMatrixError):
            return False
        return True

    def _explain_rank(self, q, v, p, t0: float) -> None:
        """Raise ModelError naming the dependent constraint rows if A is rank deficient at q."""
        if self.system.J:
            A = self.system.evaluate(q, v, self._values(p), t0)["A"]
            if np.linalg.matrix_rank(A, tol=rank_tolerance(A)) < self.system.J:
                raise ModelError("singular constraint Jacobian at the initial state: cannot project; "
                                 + dependent_rows(A))

    # ------------------------------------------------------------------ simulate
    def simulate(self, t, q0=None, v0=None, *, params: Mapping | None = None, solver=None, rtol: float = 1e-8,
                 atol=1e-10, backend: str = "native", method: str | None = None, baumgarte: tuple | str | None = None,
                 projection: bool | None = None, initial: str = "check", ic_tol: float = 1e-8,
                 max_steps: int = 1_000_000, first_step: float = 0.0, max_step: float = 0.0,
                 min_step: float = 0.0, max_order: int = 0, events: bool = True, max_events: int = 10_000,
                 suppress_alg: bool = True, alg_atol: float | None = None, jacobian: bool | None = None,
                 stop_at_outputs: bool = False, proj_tol: float = 1e-12,
                 proj_maxit: int = 10, raise_on_error: bool = True) -> Result:
        """Integrate from t[0] and return the trajectory at the times ``t``.

        ``q0``/``v0``: initial coordinates and velocities (arrays or dicts by name), checked or
        projected per ``initial`` (see :meth:`consistent_initial_state`). ``backend``:
        ``"native"`` (generated CVODE/IDA drivers) or ``"sksundae"`` (scikit-sundae's Python API
        on the same compiled functions; index-1 there has no projection, and GGL there uses a
        huge atol on lambda, mu instead of IDASetSuppressAlg).

        Index-1: ``method`` ``"adams"`` (default without projection) or ``"bdf"`` (default and
        required with projection); ``baumgarte`` (``"auto"`` or (alpha, beta), see
        :func:`~lagcodegen.api.compile_constrained`; the values used are in ``stats["alpha"]``,
        ``stats["beta"]``) and ``projection`` override the compiled defaults. GGL:
        ``suppress_alg`` (native), ``jacobian`` (generated residual Jacobian, default when
        compiled), ``alg_atol`` (absolute tolerance of lambda, mu; default
        :data:`ALGEBRAIC_ATOL`, see there), ``stop_at_outputs`` (native: step exactly to
        every output time instead of interpolating, so that the reported states satisfy the
        constraints to the Newton tolerance). Otherwise the output times are served by the
        integrator's interpolation (index-1 always): ``t = (t0, t1)`` (1001 output times) takes
        the steps that ``[t0, t1]`` takes, up to CVODE's estimate of the first step, which
        looks at the first output interval. ``atol`` may be a scalar, one value per
        (q, q') or, for GGL, one per (q, q', lambda, mu). ``events``: enable root finding.
        ``solver``: :class:`~lagcodegen.solvers.options.CVODE` (index-1) or
        :class:`~lagcodegen.solvers.options.IDA` (GGL) instead of those keywords.
        """
        if solver is not None:
            given = dict(method=method, backend=backend, max_order=max_order, jacobian=jacobian,
                         suppress_alg=suppress_alg, alg_atol=alg_atol, stop_at_outputs=stop_at_outputs)
            chosen = merge(solver, {**given, "linear_solver": "dense", "bandwidths": None},
                           {**_SIMULATE_DEFAULTS, "linear_solver": "dense", "bandwidths": None})
            if chosen["linear_solver"] != "dense" or chosen["bandwidths"] is not None:
                raise LagcodegenError("constrained systems use CVODE's dense linear solver")
            method, backend, max_order, jacobian = (chosen["method"], chosen["backend"], chosen["max_order"],
                                                    chosen["jacobian"])
            suppress_alg, alg_atol, stop_at_outputs = (chosen["suppress_alg"], chosen["alg_atol"],
                                                       chosen["stop_at_outputs"])
            expected = "IDA" if self.formulation == "ggl" else "CVODE"
            if type(solver).__name__ != expected:
                raise LagcodegenError(f"formulation {self.formulation!r} runs on {expected}, got solver={solver!r}")
        t = self._times(t)
        if q0 is None:
            raise LagcodegenError("q0 is required")
        p = self._default_p if params is None else self.parameter_vector(params)
        ggl = self._ggl
        y0, yy0, yp0 = self._initial_values(float(t[0]), q0, v0, p, initial, ic_tol, ggl)
        roots = bool(events) and self._has_events
        if backend not in ("native", "sksundae"):
            raise LagcodegenError(f"backend must be 'native' or 'sksundae', got {backend!r}")
        if self.formulation == "index1":
            projection = self.projection if projection is None else bool(projection)
            alpha, beta = self._stabilization(baumgarte, projection, float(t[0]), y0, p, backend == "native")
            if method is None:
                method = "bdf" if projection else "adams"
            if method not in METHODS:
                raise LagcodegenError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
            if projection and method != "bdf":
                raise LagcodegenError("projection onto the constraints (CVodeSetProjFn) needs method='bdf': "
                                      "CVODE supports projection with BDF only")
            if type(rtol) is float and type(atol) is float and 0 < rtol < math.inf and 0 <= atol < math.inf \
                    and backend == "native":
                atol_arr = atol  # what tolerances() returns for these
            else:
                rtol, atol_arr = tolerances(rtol, atol, 2 * self.n, scalar=backend == "native")
            if backend == "native":
                res = cvode.solve_index1(self, t, y0, p, method, rtol, atol_arr, float(alpha), float(beta), projection,
                                      proj_tol, proj_maxit, roots, max_events, max_steps, first_step, max_step,
                                      min_step, max_order)
            else:
                if projection:
                    raise LagcodegenError("the sksundae backend has no projection (scikit-sundae does not expose "
                                          "CVodeSetProjFn): use backend='native'")
                res = sksundae.solve_index1(self, t, y0, p, method, rtol, atol_arr, float(alpha), float(beta), roots,
                                           max_steps, first_step, max_step, min_step, max_order)
                res.stats.update(alpha=float(alpha), beta=float(beta))
            res.stats["projection"] = projection
        else:
            if method not in (None, "bdf"):
                raise LagcodegenError("IDA integrates with BDF only (method='bdf')")
            method = "bdf"
            if jacobian is None:
                jacobian = self.info.ggl_jac
            if jacobian and not self.info.ggl_jac:
                raise LagcodegenError("jacobian=True but the residual Jacobian was not generated "
                                      "(compile_constrained(..., jacobian=False))")
            if yy0 is None:
                yy0, yp0 = self._ggl_initial(t[0], y0, p)
            cached = self._ggl_atol
            if (type(atol) is float and alg_atol is None and type(rtol) is float and 0 < rtol < math.inf
                    and cached[0] == _DOUBLE(atol)):
                atol_arr = cached[1]  # what tolerances() gave for this atol last time
            else:
                rtol, atol_arr = tolerances(rtol, atol, self.info.ng, 2 * self.n)
                if np.asarray(atol).size != self.info.ng:  # lambda, mu: see ALGEBRAIC_ATOL
                    atol_arr[2 * self.n:] = ALGEBRAIC_ATOL if alg_atol is None else check_finite(alg_atol, "alg_atol")
                    if type(atol) is float and alg_atol is None:  # kept (read-only) for the next call
                        atol_arr.flags.writeable = False
                        self._ggl_atol = (_DOUBLE(atol), atol_arr)
            if backend == "native":
                res = ida.solve_ggl(self, t, yy0, yp0, p, rtol, atol_arr, bool(suppress_alg), bool(jacobian), roots,
                                      max_events, max_steps, first_step, max_step, min_step, max_order,
                                      bool(stop_at_outputs))
            else:
                res = sksundae.solve_ggl(self, t, yy0, yp0, p, rtol, atol_arr, bool(jacobian), roots, max_steps,
                                         first_step, max_step, min_step, max_order)
        res.parameters = self._default_parameters.copy() if p is self._default_p else dict(zip(self.param_names, p))
        res.n_coordinates = self._n
        res.formulation = self.formulation
        if raise_on_error and not res.success:
            cls = SingularMassMatrixError if res.stats.get("model_error") == ERR_SINGULAR else SolverError
            t_end = res.stats.get("t_reached", res.t[-1] if res.t.size else t[0])
            raise cls(res.message, t=t_end, flag=res.status, result=res)
        return res

    def _times(self, t) -> np.ndarray:
        """:func:`~lagcodegen.util.output_times`, with the 1001 times of the last pair (t0, t1) of
        Python numbers kept (read-only) for the next call with the same pair."""
        if (type(t) is tuple or type(t) is list) and len(t) == 2:
            a, b = t
            if (type(a) is float or type(a) is int) and (type(b) is float or type(b) is int):
                key = (a, b, a == 0 and math.copysign(1.0, a) < 0, b == 0 and math.copysign(1.0, b) < 0)
                last = self._pair_times
                if last is not None and last[0] == key:
                    return last[1]
                times = output_times(t)
                times.flags.writeable = False
                self._pair_times = (key, times)
                return times
        return output_times(t)

    def _initial_values(self, t0: float, q0, v0, p: np.ndarray, initial, ic_tol, ggl: bool):
        """(y0, yy0, yp0): the initial state of a run, checked or projected per ``initial`` and with
        a regular augmented matrix there, and for GGL the initial values (yy0, yp0) of IDA (else
        None, None). One call of the runtime's ``lcg_dae_initial_state`` on the model's table;
        when a check fails there, the same checks function by function, which raise the error
        that says why (:meth:`consistent_initial_state`)."""
        fn = self.c_initial_state
        mode = _INITIAL_MODES.get(initial) if type(initial) is str else None
        if mode is not None and (isinstance(ic_tol, float) or type(ic_tol) is int):
            names = self._coord_names
            fb, darr = self.ffi.from_buffer, self._double_array
            y = self.ffi.new(darr, _state_values(q0, names, "q0") + _state_values(v0, names, "v0"))
            if ggl:
                yy, yp = np.empty(self.info.ng), np.empty(self.info.ng)
                rc = fn(t0, y, self.c_params(p), mode, float(ic_tol), self._nineq, fb(darr, yy), fb(darr, yp))
                if rc == 0:
                    return yy[: 2 * self._n], yy, yp
            else:
                yy = np.empty(2 * self._n)
                rc = fn(t0, y, self.c_params(p), mode, float(ic_tol), self._nineq, fb(darr, yy), self.ffi.NULL)
                if rc == 0:
                    return yy, None, None
        y0 = self.consistent_initial_state(t0, q0, v0, p, initial=initial, ic_tol=ic_tol)
        try:
            self.kkt(t0, y0, p)
        except SingularMassMatrixError as exc:
            raise SingularMassMatrixError(f"at the initial state: {exc}", t=t0) from None
        return y0, None, None

    def native_events(self, max_events: int) -> NativeEvents:
        """An events struct for a native run (from the pool of this simulation when one is free;
        the drivers reset its counters); hand it back with :meth:`release_events`."""
        pool = self._event_pool.get(max_events)
        if pool:
            try:
                return pool.pop()
            except IndexError:  # taken by another thread meanwhile
                pass
        ny = self.info.ng if self.formulation == "ggl" else 2 * self._n
        return NativeEvents(self.ffi, self.events_type, self.info.events, ny, max_events)

    def release_events(self, events: NativeEvents) -> None:
        """Return an events struct of :meth:`native_events` (its records already made)."""
        pools = self._event_pool
        if events.max_events not in pools and len(pools) >= _EVENT_POOL_KEYS:
            pools.clear()
        pool = pools.setdefault(events.max_events, [])
        if len(pool) < _EVENT_POOL:
            pool.append(events)

    def ensemble(self, t, q0=None, v0=None, *, params=None, threads=None, save="final", executor=None,
                 progress=None, max_wall: float = 0.0, chunk_size=None, **options):
        """N runs in one call into the generated C (index-1: CVODE, GGL: IDA) over a thread pool,
        bit-identical to :meth:`simulate` member by member; see
        :meth:`lagcodegen.solvers.compiled.CompiledModel.ensemble` for the arguments, and
        :meth:`simulate` for ``options``. Members whose initial state is rejected get status -84."""
        return ensemble_constrained(self, t, q0, v0, params=params, threads=threads, save=save, executor=executor,
                                    progress=progress, max_wall=max_wall, chunk_size=chunk_size, **options)

    def __reduce__(self):
        """Pickled by the system and the generated code (the compiled module is rebuilt from the
        receiving process's cache)."""
        return ConstrainedSimulation, (self.system, self.formulation, self.compiled, self.info, self.baumgarte,
                                       self.projection)

    def cvc_solve_many(self, e, opt) -> int:
        """The runtime's index-1 ensemble driver (``lcg_cvc_solve_many``) on this model: ``e`` a
        ``lcg_cvc_ensemble *`` (its model field is set here)."""
        e.model = self.table
        return self.lib.lcg_cvc_solve_many(e, opt)

    def ida_solve_many(self, e, opt) -> int:
        """The runtime's GGL ensemble driver (``lcg_ida_solve_many``) on this model: ``e`` a
        ``lcg_ida_ensemble *`` (its model field is set here)."""
        if self.c_ggl_res is None:
            raise LagcodegenError("the GGL residual is compiled with formulation='ggl' only")
        e.model = self.table
        return self.lib.lcg_ida_solve_many(e, opt)

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
        if self.c_ggl_res is None:
            raise LagcodegenError("the GGL residual is compiled with formulation='ggl' only")
        yy, yp = self._y(yy, self.info.ng, "yy"), self._y(yp, self.info.ng, "yp")
        rc = self.c_ggl_res(float(t), self._ptr(yy), self._ptr(yp), self._ptr(p), self._ptr(rr))
        self._check(rc, t, "GGL residual")
        return rr

    def ggl_jacobian(self, t, cj, yy, yp, params=None) -> np.ndarray:
        """dF/dyy + cj dF/dyp of the GGL residual (ng x ng)."""
        p = self._p(params)
        ng = self.info.ng
        J = np.empty((ng, ng), order="F")
        if self.c_ggl_jac is None:
            raise LagcodegenError("the GGL residual Jacobian is compiled with formulation='ggl', jacobian=True only")
        yy, yp = self._y(yy, self.info.ng, "yy"), self._y(yp, self.info.ng, "yp")
        rc = self.c_ggl_jac(float(t), float(cj), self._ptr(yy), self._ptr(yp), self._ptr(p),
                            self.ffi.from_buffer("double[]", J.T))
        self._check(rc, t, "GGL Jacobian")
        return J

    def ggl_multiplier_outputs(self, yy: np.ndarray, copy: bool = True) -> dict:
        """The GGL multipliers mu_k of the velocity-level holonomic rows, as outputs (column
        views of ``yy`` with ``copy=False``)."""
        first = 2 * self._n + self.info.J
        cols = yy.T[first: first + self.info.JH]
        return dict(zip(self._mu_names, cols.copy() if copy else cols))


def _state_values(val, names: list, what: str) -> list:
    """:func:`~lagcodegen.util.state_values`, without its general checks for the common input:
    a list or tuple of len(names) finite numbers, or a 1-D float64 array of them."""
    out = None
    if (type(val) is list or type(val) is tuple) and len(val) == len(names):
        try:
            out = [float(x) for x in val]
        except (TypeError, ValueError):
            out = None
    elif type(val) is np.ndarray and val.dtype == np.float64 and val.ndim == 1 and val.size == len(names):
        out = val.tolist()
    if out is not None and all(map(math.isfinite, out)):
        return out
    return state_values(val, names, what)


def _norm(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.max(np.abs(x))) if x.size else 0.0


_SIMULATE_DEFAULTS = {name: prm.default for name, prm in
                      inspect.signature(ConstrainedSimulation.simulate).parameters.items()}
