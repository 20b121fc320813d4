"""Integrate a compiled scene (an ODE y' = f(t, y), y = (q, q', z)): the options check and the
choice of the solver family.

* ``backend="native"``: the generated C driver calls CVODE directly (no Python in the solver
  loop), :mod:`.cvode`;
* ``backend="sksundae"``: scikit-sundae's Python API calls the same compiled functions through
  cffi (one Python callback per right-hand-side evaluation), :mod:`.sksundae`;
* ``method="taylor"``: the generated Taylor-series integrator (no SUNDIALS), :mod:`.taylor`;
* ``method="auto"``: Taylor or Adams by the measured rule of :func:`choose_method`.
"""

from __future__ import annotations

import inspect
import math

import numpy as np

from ..errors import LagcodegenError, SingularMassMatrixError, SolverError
from ..result import Result
from ..util import output_times
from .base import LINEAR_SOLVERS, METHODS, check_initial_mass_matrix, initial_state, tolerances
from .cvode import band_widths, solve_native
from .options import merge
from .sksundae import solve_sksundae
from .taylor.run import run_taylor


def simulate(cm, t, q0=None, v0=None, *, y0=None, z0=None, params: dict | None = None, solver=None,
             method: str = "adams", rtol: float = 1e-8, atol=1e-10, jacobian: bool | None = None,
             backend: str = "native", max_steps: int = 1_000_000, first_step: float = 0.0,
             max_step: float = 0.0, min_step: float = 0.0, max_order: int = 0,
             linear_solver: str = "dense", bandwidths: tuple[int, int] | None = None,
             events=(), order: int | None = None, raise_on_error: bool = True) -> Result:
    """Integrate the compiled scene ``cm`` and return the trajectory at the times ``t``.

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
        An option object of one solver family (:class:`~lagcodegen.solvers.options.CVODE`,
        :class:`~lagcodegen.solvers.options.Taylor`) instead of the keywords below.
    method:
        ``"adams"`` (nonstiff), ``"bdf"`` (stiff), ``"taylor"`` (the generated Taylor-series
        integrator: high order, no SUNDIALS; built on first use) or ``"auto"``
        (:func:`choose_method`).
    jacobian:
        Use the generated Jacobian (default when the scene has one) or CVODE's difference
        quotients (``False``).
    linear_solver:
        ``"dense"`` (default), ``"fixedpoint"`` (native backend: no linear solver, CVODE's
        fixed-point nonlinear iteration; for nonstiff problems with Adams, no Jacobian at all)
        or ``"band"`` (native backend): CVODE's band solver on the
        interleaved state (q_1, q_1', q_2, q_2', ..., z) with the bandwidths of the scene's
        Jacobian pattern (:meth:`Scene.jacobian_pattern`) in that order, or ``bandwidths``
        = (upper, lower) if given. The Jacobian is the sparse one
        (``Scene(sparse_jacobian=True)``) when the scene has it, else the dense one, else
        CVODE's band difference quotients (mu + ml + 1 RHS calls per Jacobian). Pays off for
        chains with nearest-neighbour coupling and a (block-)diagonal mass matrix.
    max_steps:
        Step budget over the whole run. ``max_step``: largest step (0: none).
    events:
        ``method="taylor"`` only: :class:`~lagcodegen.model.events.Event` items (expressions in
        q, q', t and the parameters) located by root finding on each step's polynomial.
    order:
        ``method="taylor"``: order of the series (default from ``rtol``).
    raise_on_error:
        Raise :class:`SolverError` on failure (default); otherwise return the partial result
        with a negative ``status``.
    """
    if solver is not None:
        given = dict(method=method, jacobian=jacobian, backend=backend, max_order=max_order,
                     linear_solver=linear_solver, bandwidths=bandwidths, order=order)
        chosen = merge(solver, given, _DEFAULTS)
        method, jacobian, backend, max_order = chosen["method"], chosen["jacobian"], chosen["backend"], \
            chosen["max_order"]
        linear_solver, bandwidths, order = chosen["linear_solver"], chosen["bandwidths"], chosen["order"]
    t = output_times(t)
    y = initial_state(cm, q0, v0, y0, z0)
    if not all(map(math.isfinite, y.tolist())):
        raise LagcodegenError("the initial state has non-finite values")
    p = cm.parameter_vector(params)
    rtol, atol_arr = tolerances(rtol, atol, cm.ny, scalar=True)
    if method == "auto":
        method = choose_method(cm.n, rtol)
    runner = FAMILIES.get(method)
    if runner is not None:
        res = runner(cm, t, y, p, rtol=rtol, atol=atol_arr, max_step=max_step, max_steps=int(max_steps),
                     order=order, events=events)
    else:
        if method not in METHODS:
            raise LagcodegenError(f"method must be one of {', '.join([*METHODS, *FAMILIES, 'auto'])}, "
                                  f"got {method!r}")
        if events:
            raise LagcodegenError("events on an unconstrained model need method='taylor' (the CVODE driver of "
                                  "a plain scene has no root finding; constrained systems have events on CVODE "
                                  "and IDA)")
        res = _cvode(cm, t, y, p, method, rtol, atol_arr, jacobian, backend, int(max_steps), first_step, max_step,
                     min_step, max_order, linear_solver, bandwidths)
    res.parameters = dict(zip(cm.param_names, p))
    res.n_coordinates = cm.n
    if not res.success and res.t.size <= 1:  # failed at the start: say which value it was
        check_initial_outputs(cm, t[0], y, p)
        if res.stats.get("model_error") == 1:
            check_initial_mass_matrix(cm, t[0], y, p)
    if raise_on_error and not res.success:
        cls = SingularMassMatrixError if res.stats.get("model_error") == 1 else SolverError
        raise cls(res.message, t=res.stats.get("t_reached", res.t[-1] if res.t.size else t[0]), flag=res.status,
                  result=res)
    return res


def check_initial_outputs(cm, t0: float, y: np.ndarray, p: np.ndarray) -> None:
    """Raise SolverError naming every output that is not finite at the initial state (each
    family would stop there anyway, with nothing to say which value it was)."""
    nout = cm.code.nout
    if not nout or cm.c_outputs is None:
        return
    out = np.empty(nout)
    cm.c_outputs(float(t0), cm.ffi.from_buffer("double[]", y), cm.c_params(p), cm.ffi.from_buffer("double[]", out))
    values = out.tolist()
    if all(map(math.isfinite, values)):
        return
    bad = [f"{name} = {v}" for name, v in zip(cm.output_names, values) if not math.isfinite(v)]
    more = f" and {len(bad) - 5} more" if len(bad) > 5 else ""
    raise SolverError(f"output{'s' if len(bad) > 1 else ''} not finite at the initial state: "
                      f"{', '.join(bad[:5])}{more}", t=float(t0))


#: Solver families other than CVODE, by method name: each runs (cm, t, y, p, *, rtol, atol,
#: max_step, max_steps, order, events) -> Result on inputs checked by :func:`simulate`. A new
#: family is a folder under solvers/ plus one entry here.
FAMILIES = {"taylor": run_taylor}

_DEFAULTS = {name: prm.default for name, prm in inspect.signature(simulate).parameters.items()}


def _cvode(cm, t, y, p, method, rtol, atol, jacobian, backend, max_steps, first_step, max_step, min_step,
           max_order, linear_solver, bandwidths) -> Result:
    """The CVODE family on an ODE: options checked, then the native or the scikit-sundae runner."""
    if linear_solver not in LINEAR_SOLVERS:
        raise LagcodegenError(f"linear_solver must be one of {', '.join(LINEAR_SOLVERS)}, got {linear_solver!r}")
    band = linear_solver == "band"
    if linear_solver != "dense" and backend != "native":
        raise LagcodegenError(f"linear_solver={linear_solver!r} needs backend='native'")
    if linear_solver == "fixedpoint":
        jacobian = False  # functional iteration uses no Jacobian
    has_jac = cm.code.jacobian or (bool(getattr(cm.code, "sparse_jacobian", False)) and backend == "native")
    if jacobian is None:
        jacobian = has_jac
    if jacobian and not has_jac:
        raise LagcodegenError("jacobian=True but the scene emits no Jacobian (Scene(jacobian=False))")
    if backend != "native":  # the native driver reports this itself, from its first RHS call
        check_initial_mass_matrix(cm, t[0], y, p)
    opts = dict(method=method, rtol=rtol, atol=atol, jacobian=bool(jacobian), max_steps=max_steps,
                first_step=first_step, max_step=max_step, min_step=min_step, max_order=max_order)
    if band:
        opts["band"] = band_widths(cm, bandwidths, y, p)
    elif linear_solver == "fixedpoint":
        opts["fixedpoint"] = True
    if backend == "native":
        if not cm.native:
            raise LagcodegenError("this module was built without the native driver (build(native=False))")
        return solve_native(cm, t, y, p, **opts)
    if backend == "sksundae":
        res = solve_sksundae(cm, t, y, p, **opts)
        # its outputs are evaluated after the run, where nothing fails: check the first row
        if res.t.size and not all(math.isfinite(v[0]) for v in res.outputs.values()):
            check_initial_outputs(cm, t[0], y, p)
        return res
    raise LagcodegenError(f"backend must be 'native' or 'sksundae', got {backend!r}")


def choose_method(n: int, rtol: float) -> str:
    """The method ``method="auto"`` picks: Taylor for up to :data:`AUTO_TAYLOR_MAX_N`
    coordinates at any tolerance, and up to :data:`AUTO_TAYLOR_TIGHT_MAX_N` at rtol <= 1e-8;
    Adams otherwise.

    Measured with ``python benchmarks/taylor.py --rounds 3`` (n-link pendulums, q0 = 0.1 and 1.0,
    t in [0, 10], time of ``simulate()`` at equal achieved error): Adams/Taylor time ratio 1.7-12
    for n <= 3, 1.0-2.1 at n = 5, 0.7-0.9 at n = 10 for errors >= 1e-6 but 1.0-1.7 below 1e-8,
    0.4-1.3 at n = 20 (Adams faster in most cells)."""
    if n <= AUTO_TAYLOR_MAX_N or (n <= AUTO_TAYLOR_TIGHT_MAX_N and rtol <= 1e-8):
        return "taylor"
    return "adams"


#: ``method="auto"`` integrates models with at most this many coordinates by the Taylor method
#: (see :func:`choose_method`), and up to AUTO_TAYLOR_TIGHT_MAX_N at tight tolerances.
AUTO_TAYLOR_MAX_N = 5
AUTO_TAYLOR_TIGHT_MAX_N = 10
