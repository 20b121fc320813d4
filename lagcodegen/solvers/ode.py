"""Integrate a compiled scene (an ODE y' = f(t, y), y = (q, q', z)): the options check and the
choice of the solver family.

* ``backend="native"``: the generated C driver calls CVODE directly (no Python in the solver
  loop), :mod:`.cvode`;
* ``backend="sksundae"``: scikit-sundae's Python API calls the same compiled functions through
  cffi (one Python callback per right-hand-side evaluation), :mod:`.sksundae`.
"""

from __future__ import annotations

import numpy as np

from ..errors import LagcodegenError, SingularMassMatrixError, SolverError
from ..result import Result
from ..util import check_finite, output_times
from .base import LINEAR_SOLVERS, METHODS, check_initial_mass_matrix, initial_state
from .cvode import band_widths, solve_native
from .sksundae import solve_sksundae


def simulate(cm, t, q0=None, v0=None, y0=None, z0=None, params: dict | None = None,
             method: str = "adams", rtol: float = 1e-8, atol=1e-10, jacobian: bool | None = None,
             backend: str = "native", max_steps: int = 1_000_000, first_step: float = 0.0,
             max_step: float = 0.0, min_step: float = 0.0, max_order: int = 0,
             linear_solver: str = "dense", bandwidths: tuple[int, int] | None = None,
             raise_on_error: bool = True) -> Result:
    """Integrate the compiled scene ``cm`` and return the trajectory at the times ``t``.

    Parameters
    ----------
    t:
        Output times (increasing; ``t[0]`` is the initial time), or a pair (t0, t1), which
        gives 1001 evenly spaced output times.
    q0, v0 / y0:
        Initial coordinates and velocities (arrays, or dicts by coordinate name), or the
        whole state. ``z0``: initial quadrature states (e.g. ignorable coordinates of a
        Routhian-reduced model), zeros by default.
    params:
        Run-time parameter values by name (defaults from the model).
    method:
        ``"adams"`` (nonstiff) or ``"bdf"`` (stiff).
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
        Step budget over the whole run.
    raise_on_error:
        Raise :class:`SolverError` on failure (default); otherwise return the partial result
        with a negative ``status``.
    """
    t = output_times(t)
    y = initial_state(cm, q0, v0, y0, z0)
    if not np.isfinite(y).all():
        raise LagcodegenError("the initial state has non-finite values")
    p = cm.parameter_vector(params)
    rtol = check_finite(rtol, "rtol")
    if method not in METHODS:
        raise LagcodegenError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
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
    atol_arr = np.broadcast_to(np.asarray(atol, dtype=float), (cm.ny,)).copy()
    if not np.isfinite(atol_arr).all() or (atol_arr < 0).any() or rtol < 0:
        raise LagcodegenError("tolerances must be finite and non-negative")

    if backend != "native":  # the native driver reports this itself, from its first RHS call
        check_initial_mass_matrix(cm, t[0], y, p)

    opts = dict(method=method, rtol=rtol, atol=atol_arr, jacobian=bool(jacobian), max_steps=int(max_steps),
                first_step=first_step, max_step=max_step, min_step=min_step, max_order=max_order)
    if band:
        opts["band"] = band_widths(cm, bandwidths, y, p)
    elif linear_solver == "fixedpoint":
        opts["fixedpoint"] = True
    if backend == "native":
        if not cm.native:
            raise LagcodegenError("this module was built without the native driver (build(native=False))")
        res = solve_native(cm, t, y, p, **opts)
    elif backend == "sksundae":
        res = solve_sksundae(cm, t, y, p, **opts)
    else:
        raise LagcodegenError(f"backend must be 'native' or 'sksundae', got {backend!r}")
    res.parameters = dict(zip(cm.param_names, p))
    res.n_coordinates = cm.n
    if res.stats.get("model_error") == 1 and res.stats.get("t_reached") == t[0]:
        check_initial_mass_matrix(cm, t[0], y, p)
    if raise_on_error and not res.success:
        cls = SingularMassMatrixError if res.stats.get("model_error") == 1 else SolverError
        raise cls(res.message, t=res.stats.get("t_reached", res.t[-1]), flag=res.status, result=res)
    return res


