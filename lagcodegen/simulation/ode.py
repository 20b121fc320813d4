"""The face of a compiled scene (:class:`CompiledModel`): the functions of the generated code,
checked, and its runs (:meth:`CompiledModel.simulate`) and ensembles of the ODE y' = f(t, y),
y = (q, q', z), on any registered solver family that integrates an ODE."""

from __future__ import annotations

import ctypes
import dataclasses
import functools
import math
from pathlib import Path

import numpy as np

from ..build import BuiltModule, build
from ..codegen.record import GeneratedCode, plain_code
from ..codes import ModelCode
from ..errors import LagcodegenError, SingularMassMatrixError, SolverError
from ..formulation.drawing import attaches_drawing
from ..notebook import CompiledReprMixin
from ..result import Result
from ..solvers import control
from ..solvers.artifacts import Artifacts
from ..solvers.family import Problem, Request
from ..solvers.base import initial_state, tolerances
from ..solvers.registry import resolve
from ..solvers.request import Recording
from ..util import c_vector, check_finite, output_times
from ..solvers.inputs import input_set
from ..solvers.payload import with_scene  # noqa: F401 - public here too (lagcodegen.simulation.ode.with_scene)
from .ensemble import ensemble_ode
from .fastpath import FastRuns, finish_run
from .prepared import PreparedRun
from .integrator import Integrator
from .sensitivity_integrator import SensitivityIntegrator


_DOUBLE = np.dtype(np.float64)


def _out_array(out, shape: tuple, what: str, order: str = "C") -> np.ndarray:
    """``out`` checked to be a writable float64 array of ``shape``, contiguous in ``order``
    (where the C writes its result), else a LagcodegenError naming what it must be."""
    ok = isinstance(out, np.ndarray) and out.dtype == np.float64 and out.shape == shape and out.flags.writeable \
        and (out.flags.f_contiguous if order == "F" else out.flags.c_contiguous)
    if not ok:
        raise LagcodegenError(f"{what} must be a writable, {'Fortran' if order == 'F' else 'C'}-contiguous float64 "
                              f"array of shape {shape}, got {type(out).__name__} "
                              f"{getattr(out, 'dtype', '')} {getattr(out, 'shape', '')}".rstrip())
    return out


def check_rc(rc: int, t: float, what: str) -> None:
    """Raise the error a generated model function's return code stands for (1: singular mass
    matrix, 2: a non-finite value)."""
    if rc == ModelCode.SINGULAR:
        raise SingularMassMatrixError(f"{what}: the mass matrix is singular", t=float(t))
    if rc == ModelCode.NONFINITE:
        raise SolverError(f"{what}: a computed value is not finite", t=float(t))


@dataclasses.dataclass(frozen=True)
class _Costs:
    """The measured costs of a model kept among its artifacts (None where not measurable)."""

    costs: object


class CompiledModel(CompiledReprMixin):
    """A compiled scene: the cffi module plus the layout of its arrays.

    Call :meth:`rhs`, :meth:`jac`, :meth:`outputs` from Python, or :meth:`simulate`. Every
    array handed to C is checked first (length, dtype): a wrong one raises LagcodegenError.
    """

    #: (q0, v0) a run starts from when not given: a model file's initial state (set by
    #: :func:`lagcodegen.compile_file`), else None (zeros).
    initial_defaults: tuple | None = None

    def __init__(self, code: GeneratedCode, module, path: Path, native: bool, cached: bool, table=None,
                 library=None, dae_table=None):
        self.code = code
        self.module = module
        self.ffi = module.ffi
        self.lib = module.lib
        self.path = path
        self.native = native
        self.cached = cached
        self.table = table      # the model's function table (runtime builds), else None
        self.dae_table = dae_table  # constrained code: its table for the runtime's constrained drivers
        self._library = library  # keeps the model library open
        if table is not None:
            self._bind_table(table)
        else:
            self._bind_module(code.prefix)
        self.poll = control.install(module)  # the drivers' poll callback (Ctrl-C, progress)
        self._defaults = np.array(code.param_defaults, dtype=float)
        self._default_ptr = self._ptr(self._defaults)  # the defaults' buffer for C (never written)
        self._y_shape = (code.ny,)
        # what rhs() needs at each call, looked up once
        self._rhs_fast = (self.ffi.from_buffer, self._rhs_call, table, self._y_shape, self._default_ptr)
        self.artifacts = Artifacts()  # what the families build on first use (Taylor modules, event libraries)
        self._fast_runs = FastRuns()  # simulate()'s prepared runs by option values (fastpath)

    def _bind_table(self, table) -> None:
        """The model functions through its table, the runtime's CVODE driver applied to it."""
        null, lib = self.ffi.NULL, self.lib
        self.c_rhs = table.rhs
        self.c_jac = table.jac if table.jac != null else None
        self.c_outputs = table.outputs if table.outputs != null else None
        self.c_jac_sparse = table.jac_sparse if table.jac_sparse != null else None
        self.c_outputs_batch = functools.partial(lib.lcg_outputs_batch, table) if self.c_outputs else None
        self.c_rhs_batch = functools.partial(lib.lcg_rhs_batch, table)
        self._rhs_call = lib.lcg_rhs_call  # rhs(): a direct call of the runtime, not through table.rhs
        self.native_solve = functools.partial(lib.lcg_cvode_solve, table)
        solve_many = lib.lcg_cvode_solve_many

        def native_solve_many(e, opt):
            e.model = table
            return solve_many(e, opt)

        self.native_solve_many = native_solve_many
        # the C types of the CVODE driver's options, statistics and ensemble structs
        self.options_type, self.stats_type, self.ensemble_type = ("lcg_cvode_options", "lcg_cvode_stats *",
                                                                  "lcg_cvode_ensemble")

    def _bind_module(self, p: str) -> None:
        """The model functions of a module of their own (built without the native driver)."""
        self.c_rhs = getattr(self.lib, f"{p}_rhs")
        self.c_jac = getattr(self.lib, f"{p}_jac", None)
        self.c_outputs = getattr(self.lib, f"{p}_outputs", None)
        self.c_jac_sparse = getattr(self.lib, f"{p}_jac_sparse", None)
        self.c_outputs_batch = self.c_rhs_batch = None
        c_rhs, cast = self.c_rhs, self.ffi.cast
        self._rhs_call = lambda _table, t, y, p, ydot: c_rhs(t, cast("double *", y), cast("double *", p),
                                                             cast("double *", ydot))
        self.native_solve = self.native_solve_many = None
        self.options_type = self.stats_type = self.ensemble_type = None

    @classmethod
    def from_built(cls, built: BuiltModule) -> "CompiledModel":
        return cls(built.code, built.module, built.path, built.native, built.cached, built.table, built.library,
                   built.dae_table)

    # layout
    @property
    def n(self) -> int:
        return self.code.n

    @property
    def ny(self) -> int:
        return self.code.ny

    @property
    def nq(self) -> int:
        """The number of coordinates q (the first nq entries of the state y = (q, v, z))."""
        return self.code.n

    @property
    def method_size(self) -> float:
        """The size ``method="auto"`` chooses by (:func:`~lagcodegen.solvers.registry.choose_method`):
        the coordinates, or infinity (never the Taylor method) for generalized speeds."""
        return self.n if self.code.nv is None else math.inf

    def method_costs(self, rtol: float):
        """The measured costs ``method="auto"`` weighs at ``rtol`` (:func:`lagcodegen.solvers.auto.choose_method`):
        :func:`lagcodegen.solvers.taylor.probe.measure_costs`, once per Taylor order (kept with the
        model; the Taylor integrator is built for it), or None where they cannot be measured."""
        from ..solvers.taylor.probe import measure_costs, run_order
        return self.artifacts.get(_Costs, run_order(rtol), lambda: _Costs(measure_costs(self, rtol))).costs

    @property
    def nv(self) -> int:
        """The number of speeds v (= nq unless the model has generalized speeds, e.g. quaternion joints)."""
        return self.code.speeds

    @property
    def state_names(self) -> list[str]:
        return self.code.state_names

    @property
    def param_names(self) -> list[str]:
        return self.code.param_names

    @property
    def output_names(self) -> list[str]:
        return self.code.output_names

    def parameter_vector(self, params: dict | None = None) -> np.ndarray:
        """Run-time parameter array: defaults overridden by ``params`` (name -> value)."""
        if not params:
            return self._defaults.copy()
        vals = dict(zip(self.code.param_names, self.code.param_defaults))
        for k, v in params.items():
            if k not in vals:
                raise LagcodegenError(f"{k!r} is not a run-time parameter of this scene "
                                      f"(run-time parameters: {', '.join(vals) or 'none'})")
            vals[k] = check_finite(v, f"parameter {k!r}")
        return np.array([vals[k] for k in self.code.param_names], dtype=float)

    def _ptr(self, arr):
        return self.ffi.from_buffer("double[]", arr) if arr.size else self.ffi.NULL

    def c_params(self, p: np.ndarray):
        """``p`` as the C pointer the generated drivers take (NULL without run-time parameters)."""
        return self._ptr(p)

    def _args(self, y, p):
        y = c_vector(y, self.ny, "y", self.state_names)
        p = self._defaults if p is None else c_vector(p, self.code.np, "p", self.param_names)
        return y, p

    def rhs(self, t: float, y, p=None, *, out: np.ndarray | None = None) -> np.ndarray:
        """f(t, y, p) evaluated by the compiled code (into ``out``, a float64 array of ny, if
        given). A float64 array of shape (ny,) goes straight to C, one direct call of the
        runtime's ``lcg_rhs_call`` (cheaper through cffi than the table's function pointer): its
        checks are the array's type, dtype and shape, and contiguity (``ffi.from_buffer``
        refuses a strided view, which then takes the general path). Anything else is converted
        and checked (:func:`~lagcodegen.util.c_vector`); ``out`` must be a writable, contiguous
        float64 array of shape (ny,), else a LagcodegenError names what it must be."""
        fb, call, table, shape, pp = self._rhs_fast
        if type(y) is np.ndarray and y.dtype is _DOUBLE and y.shape == shape:
            try:
                yp = fb(y)  # char[]: lcg_rhs_call takes void pointers (the cheapest buffer cffi makes)
            except ValueError:  # not contiguous
                yp = self._ptr(c_vector(y, self.ny, "y", self.state_names))
        else:
            yp = self._ptr(c_vector(y, self.ny, "y", self.state_names))
        if p is not None:
            pp = self._ptr(c_vector(p, self.code.np, "p", self.param_names))
        if out is None:
            out = np.empty(shape)
            op = fb(out)
        elif type(out) is np.ndarray and out.dtype is _DOUBLE and out.shape == shape and out.flags.writeable:
            try:  # (checking flags.writeable costs a third of from_buffer's require_writable)
                op = fb(out)
            except ValueError:  # strided
                op = fb("double[]", _out_array(out, shape, "out"))  # raises, naming what out must be
        else:
            op = fb("double[]", _out_array(out, shape, "out"))
        rc = call(table, t, yp, pp, op)
        if rc:
            check_rc(rc, t, "right-hand side")
        return out

    def rhs_batch(self, t: float, Y, p=None) -> np.ndarray:
        """f(t, y, p) of every row of ``Y`` (N x ny) in one call into C: ``p`` None (the
        defaults), one parameter vector for all rows, or an N x np array (one per row). Returns
        N x ny. A state whose right-hand side fails raises, naming its row."""
        Y = np.asarray(Y, dtype=float)
        if Y.ndim != 2 or Y.shape[1] != self.ny:
            raise LagcodegenError(f"Y must be an N x {self.ny} array of states ({', '.join(self.state_names)}), got "
                                  f"shape {Y.shape}")
        Y = np.ascontiguousarray(Y)
        P = self._defaults if p is None else np.ascontiguousarray(np.asarray(p, dtype=float))
        if P.ndim == 2 and P.shape != (Y.shape[0], self.code.np) or P.ndim == 1 and P.size != self.code.np \
                or P.ndim > 2:
            raise LagcodegenError(f"p must hold {self.code.np} values ({', '.join(self.param_names) or 'none'}), "
                                  f"one vector or one row per state, got shape {P.shape}")
        if not (np.isfinite(Y).all() and np.isfinite(P).all()):
            raise LagcodegenError("rhs_batch: the states or parameters have non-finite values")
        out = np.empty_like(Y)
        if self.c_rhs_batch is None:  # a module of its own: row by row
            for k in range(Y.shape[0]):
                out[k] = self.rhs(t, Y[k], P if P.ndim == 1 else P[k])
            return out
        failed = self.ffi.new("int *")
        rc = self.c_rhs_batch(Y.shape[0], float(t), self.ffi.from_buffer("double[]", Y),
                              self._ptr(P.ravel()), self.code.np if P.ndim == 2 else 0,
                              self.ffi.from_buffer("double[]", out), failed)
        check_rc(rc, t, f"right-hand side of row {failed[0]}")
        return out

    def jac(self, t: float, y, p=None, *, out: np.ndarray | None = None) -> np.ndarray:
        """df/dy (ny x ny) evaluated by the compiled code."""
        if self.c_jac is None:
            raise LagcodegenError("this scene has no Jacobian (Scene(jacobian=False))")
        y, p = self._args(y, p)
        ydot = self.rhs(t, y, p)
        J = np.empty((self.ny, self.ny), order="F") if out is None else _out_array(out, (self.ny, self.ny), "out",
                                                                                   order="F")
        rc = self.c_jac(float(t), self._ptr(y), self._ptr(ydot), self._ptr(p), self.ffi.from_buffer("double[]", J.T))
        check_rc(rc, t, "Jacobian")
        return J

    def outputs(self, t: float, y, p=None, *, out: np.ndarray | None = None) -> np.ndarray:
        """The scene's outputs at (t, y)."""
        y, p = self._args(y, p)
        if self.c_outputs is None:
            return np.empty(0)
        out = np.empty(self.code.nout) if out is None else _out_array(out, (self.code.nout,), "out")
        rc = self.c_outputs(float(t), self._ptr(y), self._ptr(p), self.ffi.from_buffer("double[]", out))
        check_rc(rc, t, "outputs")
        return out

    def inverse_dynamics(self, q, v, a, *, t: float = 0.0, params=None, out: np.ndarray | None = None) -> np.ndarray:
        """tau = M(q) a - F(q, v, t) (eq. 3.16 solved for the generalized forces that give the
        accelerations ``a`` at the state (q, q' = ``v``)), for models with a rigid-body tree: the
        generated ``<prefix>_inverse_dynamics`` (recursive Newton-Euler, O(n)). With v = a = 0 it is
        the static load -F(q, 0, t), e.g. the gravity torques a controller compensates."""
        fn = self._inverse_dynamics_function()
        n, nv = self.n, self.nv
        y = np.concatenate([c_vector(q, n, "q"), c_vector(v, nv, "v"), np.zeros(self.ny - n - nv)])
        acc = c_vector(a, nv, "a")
        p = self._defaults if params is None else self.parameter_vector(params)
        tau = np.empty(nv) if out is None else _out_array(out, (nv,), "out")
        dp = ctypes.POINTER(ctypes.c_double)
        rc = fn(float(t), y.ctypes.data_as(dp), acc.ctypes.data_as(dp), p.ctypes.data_as(dp), tau.ctypes.data_as(dp))
        check_rc(rc, t, "inverse dynamics")
        return tau

    def inverse_dynamics_regressor(self, q, v, a, *, t: float = 0.0, params=None) -> np.ndarray:
        """Y(q, v, a): the inverse-dynamics regressor of the rigid-body tree, n rows and 10 columns
        per body (:attr:`regressor_bodies`), Pinocchio's order: m, m c_x, m c_y, m c_z, I_xx,
        I_xy, I_yy, I_xz, I_yz, I_zz (the inertia about the body frame's origin). The tree's share
        of :meth:`inverse_dynamics` is Y pi (pi: :meth:`regressor_parameters`); the model's
        other elements (joint damping, friction, springs) are not in Y. Generated and compiled on
        first use (:mod:`lagcodegen.simulation.regressor`); it may depend on run-time parameters
        (gravity ``g``)."""
        from .regressor import compiled_regressor
        reg = compiled_regressor(self)
        return reg.matrix(q, v, a, t, self._defaults if params is None else self.parameter_vector(params))

    def regressor_parameters(self, params=None) -> np.ndarray:
        """pi: the dynamic parameters of the tree's bodies (10 each, the columns of
        :meth:`inverse_dynamics_regressor`) at the run-time parameters ``params`` (defaults)."""
        from .regressor import compiled_regressor
        return compiled_regressor(self).parameters(self._defaults if params is None else self.parameter_vector(params))

    @property
    def regressor_bodies(self) -> list[str]:
        """The links whose 10 columns :meth:`inverse_dynamics_regressor` holds, in order (each
        moving body of the tree, links on fixed joints merged into it)."""
        from .regressor import compiled_regressor
        return list(compiled_regressor(self).bodies)

    def _inverse_dynamics_function(self):
        name = f"{self.code.prefix}_inverse_dynamics"
        if f"{self.code.prefix}_dynamics.c" not in self.code.files:
            raise LagcodegenError(f"model {self.code.model_name!r} has no inverse dynamics function (only models "
                                  "with a rigid-body tree, Model.link, have one)")
        if self._library is None:
            raise LagcodegenError("inverse_dynamics needs the model library of a native build (build_code(..., "
                                  "native=True), the default of compile_model)")
        fn = getattr(self._library, name)
        dp = ctypes.POINTER(ctypes.c_double)
        fn.restype, fn.argtypes = ctypes.c_int, [ctypes.c_double, dp, dp, dp, dp]
        return fn

    def simulate(self, t, q0=None, v0=None, *, y0=None, z0=None, params: dict | None = None, solver=None,
                 rtol: float = 1e-8, atol=1e-10, events=(), raise_on_error: bool = True, **options) -> Result:
        """Integrate the scene and return the trajectory at the times ``t``.

        A call with the option values (types included) of an earlier one takes the fast path
        (:mod:`.fastpath`): its family's run prepared once, the result's statistics, outputs and
        parameters by name made when first read; the same checks and errors, bit-identical results.

        Parameters
        ----------
        t:
            Output times (increasing; ``t[0]`` is the initial time): an array is taken as it is
            (two times give two rows); a list or tuple (t0, t1) gives 1001 evenly spaced times.
        q0, v0 / y0:
            Initial coordinates and velocities (arrays, or dicts by coordinate name), or the
            whole state. ``z0``: initial quadrature states (e.g. ignorable coordinates of a
            Routhian-reduced model), zeros by default.
        params:
            Run-time parameter values by name (defaults from the model).
        solver:
            A solver family object: :class:`~lagcodegen.solvers.cvode.CVODE` (default; method,
            linear solver, Jacobian, backend, budgets) or :class:`~lagcodegen.solvers.taylor.Taylor`
            (the generated Taylor-series integrator, built on first use).
        rtol, atol:
            Tolerances (``atol`` a scalar or one value per state).
        events:
            :class:`~lagcodegen.model.events.Event` items (name, expression in q, q', z, t, the
            parameters and the names of the scene's outputs, direction, terminal), located on
            every family: CVODE's root finding on their compiled functions (native and
            scikit-sundae), the Taylor method on each step's polynomial. Found in ``Result.events``
            (time, state, direction); a terminal event ends the run with its state as the last row.
        raise_on_error:
            Raise :class:`SolverError` on failure (default); otherwise return the partial result
            with a negative ``status``.
        inputs (in ``options``):
            Input signals by name (the model's ``Model.input``): a
            :class:`~lagcodegen.solvers.inputs.Table` or a pair (times, values) (linear), computed
            in C at each evaluation time; the integrator stops and restarts where an input jumps or
            kinks (``Table(restart=...)``; their number in ``res.stats["restarts"]``). Native
            CVODE, and Taylor (each input a cubic of t in the jet, the run split at every
            breakpoint); scikit-sundae refuses them.
        options:
            The family's fields as keywords, made into the family object by
            :func:`lagcodegen.solvers.registry.resolve`: ``method`` "adams", "bdf", "taylor" or
            "auto" (:func:`~lagcodegen.solvers.registry.choose_method`), ``jacobian``,
            ``linear_solver`` ("dense", "band", "fixedpoint"), ``bandwidths``, ``backend``
            ("native", "sksundae"), ``max_order``, ``order`` (Taylor), ``max_steps`` (steps over the
            whole run), ``max_step``, ``first_step``, ``min_step``, ``max_wall``; a keyword the
            family does not have raises LagcodegenError naming it.
        """
        fast = self._fast_runs.get(solver, rtol, atol, options) if not events else \
            self._fast_runs.get_events(solver, rtol, atol, options, events)
        if fast is not None:
            return fast(self, t, q0, v0, y0, z0, params, raise_on_error)
        res = self._simulate(t, q0, v0, y0=y0, z0=z0, params=params, solver=solver, rtol=rtol, atol=atol,
                             events=events, raise_on_error=raise_on_error, **options)
        if options.get("inputs") is None:
            self._fast_runs.learn(self, solver, rtol, atol, options, events)
        return res

    def prepare(self, t, *, solver=None, rtol: float = 1e-8, atol=1e-10, events=(), **options) -> PreparedRun:
        """A run with its output times ``t``, solver family, tolerances, ``events`` and options
        fixed once (:class:`~lagcodegen.simulation.prepared.PreparedRun`), to call with the
        initial state and parameters alone: ``run = sim.prepare(t, method="bdf", rtol=1e-10)``,
        then ``run(q0=..., params=...)`` as often as needed. Each call returns what
        ``simulate(t, q0, ..., **options)`` returns, bit for bit; where the family prepares the
        run (``run.prepared``: native CVODE, also with sensitivities; Taylor, also with events)
        its options struct and arrays are made here, once. Every option is checked here."""
        return PreparedRun(self, t, solver=solver, rtol=rtol, atol=atol, events=events, options=options)

    @attaches_drawing
    def _simulate(self, t, q0=None, v0=None, *, y0=None, z0=None, params: dict | None = None, solver=None,
                  rtol: float = 1e-8, atol=1e-10, events=(), raise_on_error: bool = True, **options) -> Result:
        """:meth:`simulate` on the full path: every option resolved and checked on this call."""
        inputs = options.pop("inputs", None)
        t = output_times(t)
        y = initial_state(self, q0, v0, y0, z0)
        # q0, v0, z0 were checked finite one by one (ModelError naming which); y0 as a whole here
        if y0 is not None and not all(map(math.isfinite, y.tolist())):
            raise LagcodegenError("the initial state has non-finite values")
        p = self.parameter_vector(params)
        rtol, atol_arr = tolerances(rtol, atol, self.ny, scalar=True)
        family = resolve("ode", solver, options, self.method_size, rtol, costs=self.method_costs)
        tables = None if inputs is None else input_set(self.code.input_names, self.param_names, inputs,
                                                       self.code.model_name, params=params)
        res = family.run("ode", Problem(self, rtol, atol_arr, t, y, p),
                         Request(events=events, inputs=tables or None))
        if tables:
            res.stats["restarts"] = int(tables.restarts_in(float(t[0]), float(t[-1])).size)
        res.parameters = dict(zip(self.param_names, p))
        res.n_coordinates = self.n
        res.n_speeds = self.code.nv
        return finish_run(self, res, t[0], y, p, raise_on_error)

    def integrator(self, *, q0=None, v0=None, y0=None, z0=None, t0: float = 0.0, params: dict | None = None,
                   solver=None, rtol: float = 1e-8, atol=1e-10, events=(), **options) -> Integrator:
        """An integration that lives between calls (:class:`~lagcodegen.simulation.integrator.Integrator`):
        ``propagate_until``, ``propagate_for``, ``propagate_grid``, ``step``; ``state``, ``params``
        (inputs among them) and ``time`` readable and writable in place.

        The initial state, parameters, tolerances and options as in :meth:`simulate` (``t0``: the
        initial time), resolved once by :func:`lagcodegen.solvers.registry.resolve`; ``method``
        "taylor" (events located on each step's polynomial) or "adams"/"bdf" (CVODE's root finding,
        as simulate's). ``max_steps`` is the step budget of one call. ``sensitivities`` (CVODE):
        a :class:`~lagcodegen.simulation.sensitivity_integrator.SensitivityIntegrator` carrying
        them (``integ.sensitivities``, writable; ``propagate_grid`` returns states and
        sensitivities).
        """
        y = initial_state(self, q0, v0, y0, z0)
        if not all(map(math.isfinite, y.tolist())):
            raise LagcodegenError("the initial state has non-finite values")
        p = self.parameter_vector(params)
        t0 = check_finite(t0, "t0")
        rtol, atol_arr = tolerances(rtol, atol, self.ny, scalar=True)
        family = resolve("ode", solver, options, self.method_size, rtol, runs="stepper", costs=self.method_costs)
        mem = np.concatenate([[t0], y, p])  # (t, y, p): the memory the C stepper works on
        stepper = family.run("ode", Problem(self, rtol, atol_arr, y=mem), Request(kind="stepper", events=events))
        if getattr(stepper, "with_sensitivities", False):  # on the stepper's memory (it may hold s)
            return SensitivityIntegrator(stepper, getattr(stepper, "mem", mem), state_names=self.state_names,
                                         param_names=self.param_names, family=stepper.family)
        return Integrator(stepper, mem, state_names=self.state_names, param_names=self.param_names,
                          family=stepper.family)

    def check_initial_outputs(self, t0: float, y: np.ndarray, p: np.ndarray) -> None:
        """Raise SolverError naming every output that is not finite at the initial state (each
        family would stop there anyway, with nothing to say which value it was)."""
        nout = self.code.nout
        if not nout or self.c_outputs is None:
            return
        out = np.empty(nout)
        self.c_outputs(float(t0), self.ffi.from_buffer("double[]", y), self.c_params(p),
                       self.ffi.from_buffer("double[]", out))
        values = out.tolist()
        if all(map(math.isfinite, values)):
            return
        bad = [f"{name} = {v}" for name, v in zip(self.output_names, values) if not math.isfinite(v)]
        more = f" and {len(bad) - 5} more" if len(bad) > 5 else ""
        raise SolverError(f"output{'s' if len(bad) > 1 else ''} not finite at the initial state: "
                          f"{', '.join(bad[:5])}{more}", t=float(t0))

    def ensemble(self, t, q0=None, v0=None, *, y0=None, z0=None, params=None, threads=None, save="final",
                 executor=None, progress=None, chunk_size=None, **options):
        """N runs in one call into the generated C, spread over ``threads`` threads (default: the
        cores), bit-identical to running each member alone with :meth:`simulate`.

        ``q0``, ``v0`` (N, n) (or (n,) shared, or dicts by name), or ``y0`` (N, ny); ``params``
        {name: (N,) array or scalar} or an (N, np) array; ``save``: "final" (states and outputs at
        the last time reached), "trajectory" (every state and output at every time) or a list of
        names (their trajectories); ``progress``: True/False, or None (a progress line on stderr
        once the run lasts 2 s); ``executor``: a concurrent.futures executor or a
        dask.distributed Client, which runs chunks of ``chunk_size`` members each. ``options``:
        those of :meth:`simulate` (solver, rtol, atol, method, max_steps, ...; ``max_wall``: the
        wall-clock limit of each member in seconds). ``inputs``: input name -> one
        :class:`~lagcodegen.solvers.inputs.Table` (or (times, values)) for every member, or a list
        of one per member (native CVODE). ``sensitivities`` (native CVODE or Taylor, events too): each
        member's forward sensitivities, bit-identical to its run alone, in the result's
        ``sensitivities`` / ``sensitivity(value, direction)`` by member. Returns
        :class:`~lagcodegen.solvers.ensemble_result.EnsembleResult`; Ctrl-C raises
        :class:`~lagcodegen.solvers.ensemble_result.EnsembleInterrupted` (a KeyboardInterrupt)
        holding what finished.
        """
        return ensemble_ode(self, t, q0, v0, y0=y0, z0=z0, params=params,
                            recording=Recording(save=save, threads=threads, progress=progress), executor=executor,
                            chunk_size=chunk_size, options=options)

    def __reduce__(self):
        """Pickled by its generated sources and their layout (names, defaults; never the .so,
        which links SUNDIALS by an absolute path, nor the symbolic scene): unpickling rebuilds
        from the receiving process's cache (memoized per process). What needs the scene there
        (the Taylor method, events, sensitivities, drawing from the states) raises a
        LagcodegenError saying so, unless the pickle was made of :func:`with_scene`."""
        return rebuild_compiled, (pickle_code(self.code), bool(self.native))


def pickle_code(code: GeneratedCode) -> GeneratedCode:
    """``code`` as it is pickled: its files, names, defaults and layout, without the scene (the
    symbolic scene is many times the size of the C it was generated into)."""
    return plain_code(code)


_REBUILT: dict = {}


def rebuild_compiled(code, native: bool):
    """A CompiledModel from its generated code: built into (or loaded from) this process's cache
    once per process (the cache's atomic publish makes concurrent builds by several workers safe)."""
    key = (code.prefix, tuple(sorted(code.files.items())), code.cdef_extra, native)
    cm = _REBUILT.get(key)
    if cm is None:
        cm = _REBUILT[key] = CompiledModel.from_built(build(code, native=native))
    return cm


def simulate(sim, t, *args, **options) -> Result:
    """``sim.simulate(t, ...)``: a run of any compiled simulation (see its ``simulate``)."""
    return sim.simulate(t, *args, **options)
