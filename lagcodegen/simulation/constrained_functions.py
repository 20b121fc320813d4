"""The compiled functions of a constrained system as Python sees them (:class:`ConstrainedFunctions`):
the model's function table (augmented system, residuals, projection, outputs, event functions,
GGL residual and Jacobian) called with checked arrays, and the consistent initial state built
from them (checked against or projected onto the constraints, eqs. 4.1-4.3), which every
formulation's run starts from."""

from __future__ import annotations

import functools
import math
from typing import Mapping

import numpy as np

from ..errors import LagcodegenError, ModelError, SingularMassMatrixError, SolverError
from ..formulation.constrained import ConstrainedCodeInfo
from ..model.events import Event
from ..solvers.base import ERR_PROJECTION, ERR_SINGULAR
from ..theory.constraints import ConstrainedSystem, dependent_rows, rank_tolerance
from ..util import BAUMGARTE_AUTO, c_vector, check_baumgarte, state_values, state_vector
from .ode import CompiledModel

#: ``initial`` of simulate() -> the mode of the runtime's ``lcg_dae_initial_state``.
_INITIAL_MODES = {"none": 0, "check": 1, "project": 2}


class _Base:
    """What every compiled constrained system offers: layout, parameters, initial-state checks."""

    system: ConstrainedSystem
    #: (q0, v0) a run starts from when not given: a model file's initial state (set by
    #: :func:`lagcodegen.compile_file`), else None.
    initial_defaults: tuple | None = None

    @property
    def n(self) -> int:
        """Number of coordinates."""
        return self.system.model.n

    def _effective_params(self, scene_defaults: dict, p_names: list, p: np.ndarray) -> dict:
        vals = dict(scene_defaults)
        vals.update(zip(p_names, (float(x) for x in p)))
        return vals


class ConstrainedFunctions(_Base):
    """The functions of a compiled constrained system (``cm.dae_table``, lcg_dae_model.h) and its
    layout; the base of :class:`~.constrained.ConstrainedSimulation`."""

    def __init__(self, system: ConstrainedSystem, cm: CompiledModel, info: ConstrainedCodeInfo, ggl: bool):
        self.system = system
        self.compiled = cm
        self.info = info
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
        self.c_initial_state = functools.partial(lib.lcg_dae_initial_state, table)
        # layout, fixed at compile time (read on every call)
        self._n = system.model.n
        #: the state y = (q, v): nq + nv values (2 nq unless the model has generalized speeds)
        self._ny = system.model.nq + system.model.nv
        self._state_names = list(cm.state_names[: self._ny])
        self._coord_names = [q.name for q in system.model.coords]
        self._speed_names = [v.name for v in system.model.v]
        # the monitored inequalities: the first root functions (contacts have none)
        self._nineq = len(system.inequalities) - len(system.contacts)
        self._ggl = ggl
        self._mu_names = [f"mu_{k}" for k in range(info.JH)]
        self._double_array = self.ffi.typeof("double[]")
        # the default parameters (read-only) and their C pointer, for runs without ``params``
        self._default_p = cm.parameter_vector(None)
        self._default_p.flags.writeable = False
        self._default_pc = self._ptr(self._default_p)

    # ------------------------------------------------------------------ layout
    @property
    def n(self) -> int:
        """Number of coordinates."""
        return self._n

    @property
    def ny(self) -> int:
        """Size of the state y = (q, v): nq + nv (2 n unless the model has generalized speeds)."""
        return self._ny

    @property
    def nv(self) -> int:
        """Number of generalized speeds (n unless the model has generalized speeds)."""
        return self._ny - self._n

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
        return c_vector(y, self._ny if size is None else size, what, names)

    # ------------------------------------------------------------------ generated functions
    def kkt(self, t: float, y, params=None, alpha: float = 0.0, beta: float = 0.0):
        """(q'', lambda) from the augmented system at (t, y)."""
        y = self._y(y)
        p = self._p(params)
        acc, lam = np.empty(self.nv), np.empty(max(self.info.J, 1))
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

    def stabilization(self, baumgarte, projection: bool, t0: float, y0: np.ndarray, p: np.ndarray,
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
        v = state_vector(v0, [s.name for s in self.system.model.v], "v0")
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
            n_ineq = self._nineq
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
            y = self.ffi.new(darr, _state_values(q0, names, "q0") + _state_values(v0, self._speed_names, "v0"))
            if ggl:
                yy, yp = np.empty(self.info.ng), np.empty(self.info.ng)
                rc = fn(t0, y, self.c_params(p), mode, float(ic_tol), self._nineq, fb(darr, yy), fb(darr, yp))
                if rc == 0:
                    return yy[: self._ny], yy, yp
            else:
                yy = np.empty(self._ny)
                rc = fn(t0, y, self.c_params(p), mode, float(ic_tol), self._nineq, fb(darr, yy), self.ffi.NULL)
                if rc == 0:
                    return yy, None, None
        y0 = self.consistent_initial_state(t0, q0, v0, p, initial=initial, ic_tol=ic_tol)
        try:
            self.kkt(t0, y0, p)
        except SingularMassMatrixError as exc:
            raise SingularMassMatrixError(f"at the initial state: {exc}", t=t0) from None
        return y0, None, None

    # ------------------------------------------------------------------ GGL
    def _ggl_initial(self, t0, y0, p):
        """yy0 = (q, v, lambda, mu = 0), yp0 = (q', v', 0, 0) from the augmented system (q' = v,
        or q' = k(q, v, t) with generalized speeds)."""
        acc, lam = self.kkt(t0, y0, p)
        n, J, JH = self.n, self.info.J, self.info.JH
        yy0 = np.concatenate([y0, lam, np.zeros(JH)])
        qdot = y0[n:]
        if self.system.model.general:  # q' = k(q, v, t): the index-1 right-hand side's first nq rows
            ydot = np.empty(self._ny)
            self._check(self.c_crhs(float(t0), self._ptr(y0), self._ptr(p), 0.0, 0.0, self._ptr(ydot)), t0,
                        "the coordinates' rates")
            qdot = ydot[:n]
        yp0 = np.concatenate([qdot, acc, np.zeros(J + JH)])
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
        first = self._ny + self.info.J
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

