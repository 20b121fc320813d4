"""Integrate a compiled scene with SUNDIALS CVODE.

Two backends give the same :class:`~lagcodegen.result.Result`:

* ``native``: the generated C driver calls CVODE directly (no Python in the solver loop);
* ``sksundae``: scikit-sundae's Python API calls the same compiled functions through cffi
  (one Python callback per right-hand-side evaluation, about 5 us each).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from .build import CompiledModel
from .errors import LagcodegenError, ModelError, SingularMassMatrixError, SolverError
from .model import check_finite
from .result import Result

METHODS = {"adams": 1, "bdf": 2}
LINEAR_SOLVERS = ("dense", "band", "fixedpoint")


def output_times(t) -> np.ndarray:
    """Output times as an array: ``t`` itself, or 1001 evenly spaced times for a pair (t0, t1)."""
    t = np.asarray(t, dtype=float).ravel()
    if t.size == 2:
        t = np.linspace(t[0], t[1], 1001)
    if t.size < 2 or not np.isfinite(t).all() or not (t[1:] > t[:-1]).all():
        raise LagcodegenError("t must be at least two finite, strictly increasing times")
    return t


def state_vector(val, names: list[str], what: str) -> np.ndarray:
    """Values for ``names`` from None (zeros), a mapping by name (missing: 0) or a sequence."""
    if val is None:
        return np.zeros(len(names))
    if isinstance(val, Mapping):
        unknown = set(val) - set(names)
        if unknown:
            raise ModelError(f"{what}: unknown coordinate(s) {', '.join(sorted(unknown))}")
        return np.array([float(val.get(k, 0.0)) for k in names])
    arr = np.array(val, dtype=float).ravel()
    if arr.size != len(names):
        raise ModelError(f"{what} has {arr.size} values, expected {len(names)} ({', '.join(names)})")
    if not np.isfinite(arr).all():
        raise ModelError(f"{what} has non-finite values")
    return arr


def _initial_state(cm: CompiledModel, q0, v0, y0, z0=None) -> np.ndarray:
    n = cm.n
    if y0 is not None:
        if q0 is not None or v0 is not None or z0 is not None:
            raise LagcodegenError("give either y0 or q0/v0, not both")
        y = np.array(y0, dtype=float).ravel()
        if y.size != cm.ny:
            raise LagcodegenError(f"y0 has {y.size} values, the state has {cm.ny}: {', '.join(cm.state_names)}")
        return y

    names = cm.state_names
    return np.concatenate([state_vector(q0, names[:n], "q0"), state_vector(v0, names[:n], "v0"),
                           state_vector(z0, names[2 * n:], "z0")])


def simulate(cm: CompiledModel, t, q0=None, v0=None, y0=None, z0=None, params: dict | None = None,
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
    y = _initial_state(cm, q0, v0, y0, z0)
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
        _check_initial_mass_matrix(cm, t[0], y, p)

    opts = dict(method=method, rtol=rtol, atol=atol_arr, jacobian=bool(jacobian), max_steps=int(max_steps),
                first_step=first_step, max_step=max_step, min_step=min_step, max_order=max_order)
    if band:
        opts["band"] = band_widths(cm, bandwidths, y, p)
    elif linear_solver == "fixedpoint":
        opts["fixedpoint"] = True
    if backend == "native":
        if not cm.native:
            raise LagcodegenError("this module was built without the native driver (build(native=False))")
        res = _solve_native(cm, t, y, p, **opts)
    elif backend == "sksundae":
        res = _solve_sksundae(cm, t, y, p, **opts)
    else:
        raise LagcodegenError(f"backend must be 'native' or 'sksundae', got {backend!r}")
    res.parameters = dict(zip(cm.param_names, p))
    res.n_coordinates = cm.n
    if res.stats.get("model_error") == 1 and res.stats.get("t_reached") == t[0]:
        _check_initial_mass_matrix(cm, t[0], y, p)
    if raise_on_error and not res.success:
        cls = SingularMassMatrixError if res.stats.get("model_error") == 1 else SolverError
        raise cls(res.message, t=res.stats.get("t_reached", res.t[-1]), flag=res.status, result=res)
    return res


CVODE_FLAG_TEXT = {
    -1: "too many steps (max_steps reached); raise max_steps or loosen the tolerances",
    -2: "tolerance too tight for machine precision",
    -3: "error test failed repeatedly or with |h| = hmin",
    -4: "corrector convergence failed repeatedly",
    -8: "the right-hand side failed unrecoverably",
    -9: "the right-hand side failed at the first call",
    -10: "the right-hand side failed repeatedly with recoverable errors (non-finite values)",
}


def _message(flag: int, model_error: int, detail: str) -> str:
    if flag >= 0:
        return "success"
    if model_error == 1:
        return "the mass matrix is singular"
    if model_error == 2:
        return "a computed value is not finite"
    text = CVODE_FLAG_TEXT.get(flag, f"CVODE failed with flag {flag}")
    return f"{text}: {detail}" if detail else text


def band_widths(cm: CompiledModel, bandwidths=None, y=None, p=None) -> tuple[int, int]:
    """(upper, lower) bandwidths of the band solver for ``cm``: ``bandwidths`` if given, else
    from the scene's Jacobian pattern in the interleaved order (:func:`scene.band_order`); a
    module without a recorded pattern (e.g. Fortran) is probed numerically at ``y``."""
    from .scene import band_order
    from .scene import bandwidths as widths
    if bandwidths is not None:
        mu, ml = (int(b) for b in bandwidths)
        if not (0 <= mu < cm.ny and 0 <= ml < cm.ny):
            raise LagcodegenError(f"bandwidths must lie in [0, {cm.ny - 1}], got {bandwidths!r}")
        return mu, ml
    pattern = getattr(cm.code, "jac_pattern", None)
    if pattern is None:
        pattern = _probe_pattern(cm, y, p)
    return widths(pattern, band_order(cm.n, cm.code.nz))


def _probe_pattern(cm: CompiledModel, y, p) -> np.ndarray:
    """Nonzero pattern of df/dy from forward differences at y and at two perturbed states."""
    rng = np.random.default_rng(12345)
    y = np.zeros(cm.ny) if y is None else np.asarray(y, dtype=float)
    pattern = np.zeros((cm.ny, cm.ny), dtype=bool)
    for yy in (y, y + 0.1 * rng.standard_normal(cm.ny), y + 0.1 * rng.standard_normal(cm.ny)):
        try:
            f0 = cm.rhs(0.0, yy, p)
        except LagcodegenError:
            continue
        for j in range(cm.ny):
            y1 = yy.copy()
            y1[j] += 1e-6 * max(1.0, abs(yy[j]))
            try:
                pattern[:, j] |= cm.rhs(0.0, y1, p) != f0
            except LagcodegenError:
                pattern[:, j] = True
    return pattern


def _check_initial_mass_matrix(cm: CompiledModel, t0: float, y: np.ndarray, p: np.ndarray) -> None:
    """Raise SingularMassMatrixError naming the state if M is singular at (t0, y)."""
    try:
        cm.rhs(t0, y, p)
    except SingularMassMatrixError as exc:
        raise SingularMassMatrixError(
            "the mass matrix is singular at the initial state "
            f"({', '.join(f'{k}={v:g}' for k, v in zip(cm.state_names, y))})", t=float(t0)) from exc


def _solve_native(cm, t, y0, p, method, rtol, atol, jacobian, max_steps, first_step, max_step,
                  min_step, max_order, band=None, fixedpoint=False) -> Result:
    ffi, lib, pre = cm.ffi, cm.lib, cm.code.prefix
    nt = t.size
    yout = np.empty((nt, cm.ny))  # rows past st.nt_done are cut off below
    out = np.empty((nt, max(cm.code.nout, 1)))
    opt = ffi.new(f"{pre}_options *")
    st = ffi.new(f"{pre}_stats *")
    opt.method = METHODS[method]
    opt.jacobian = int(jacobian)
    opt.rtol = rtol
    opt.atol = float(atol[0])
    atol_c = ffi.from_buffer("double[]", atol) if (atol != atol[0]).any() else ffi.NULL
    opt.atol_vec = atol_c
    opt.max_steps = max_steps
    opt.first_step = first_step
    opt.max_step = max_step
    opt.min_step = min_step
    opt.max_order = max_order
    opt.linear_solver = 1 if band else 2 if fixedpoint else 0
    opt.mupper, opt.mlower = band if band else (0, 0)
    pp = ffi.from_buffer("double[]", p) if p.size else ffi.NULL
    flag = getattr(lib, f"{pre}_cvode_solve")(pp, ffi.from_buffer("double[]", y0), nt,
                                              ffi.from_buffer("double[]", t), ffi.from_buffer("double[]", yout),
                                              ffi.from_buffer("double[]", out), opt, st)
    done = st.nt_done
    stats = dict(steps=st.nsteps, rhs_evals=st.nrhs + st.nrhs_dq, rhs_evals_dq=st.nrhs_dq, jac_evals=st.njac,
                 lin_setups=st.nlinsetups, err_test_fails=st.netfails, nonlin_iters=st.nniters,
                 nonlin_conv_fails=st.nncfails, t_reached=st.t_reached, h_last=st.h_last,
                 model_error=st.model_error)
    detail = ffi.string(st.message).decode(errors="replace") if flag < 0 else ""
    if done < nt:
        t, yout, out = t[:done].copy(), yout[:done].copy(), out[:done].copy()
    return Result(t=t, y=yout, state_names=list(cm.state_names),
                  outputs={k: out[:, i] for i, k in enumerate(cm.output_names)},
                  stats=stats, status=int(flag), message=_message(flag, st.model_error, detail),
                  backend="native", method=method)


def _solve_sksundae(cm, t, y0, p, method, rtol, atol, jacobian, max_steps, first_step, max_step,
                    min_step, max_order) -> Result:
    from sksundae.cvode import CVODE

    ffi, ny = cm.ffi, cm.ny
    crhs, cjac = cm._rhs, cm._jac
    pp = ffi.from_buffer("double[]", p) if p.size else ffi.NULL
    state = {"model_error": 0, "t": float(t[0])}
    jbuf = np.empty((ny, ny), order="F")

    def rhsfn(tt, y, yp):
        rc = crhs(tt, ffi.from_buffer("double[]", y), pp, ffi.from_buffer("double[]", yp, require_writable=True))
        if rc == 1:
            state["model_error"], state["t"] = 1, tt
            yp[:] = np.nan
        elif rc:
            yp[:] = np.nan

    def jacfn(tt, y, yp, JJ):
        rc = cjac(tt, ffi.from_buffer("double[]", y), ffi.from_buffer("double[]", yp), pp,
                  ffi.from_buffer("double[]", jbuf.T))
        if rc:
            jbuf[:] = np.nan
        JJ[:, :] = jbuf

    options = dict(method="Adams" if method == "adams" else "BDF", rtol=rtol,
                   atol=atol if (atol != atol[0]).any() else float(atol[0]),
                   max_num_steps=max_steps, first_step=first_step, max_step=max_step, min_step=min_step)
    if max_order:
        options["max_order"] = max_order
    if jacobian:
        options["jacfn"] = jacfn
    solver = CVODE(rhsfn, **options)
    soln = solver.solve(t, y0)
    done = len(soln.t)
    y = np.asarray(soln.y, dtype=float).reshape(done, ny)
    outs = np.full((done, cm.code.nout), np.nan)
    if cm.code.nout and done:
        tt = np.ascontiguousarray(soln.t, dtype=float)
        yy = np.ascontiguousarray(y)
        batch = getattr(cm.lib, f"{cm.code.prefix}_outputs_batch", None)
        if batch is not None:  # one C call for all rows
            batch(done, ffi.from_buffer("double[]", tt), ffi.from_buffer("double[]", yy), pp,
                  ffi.from_buffer("double[]", outs))
        else:
            for k in range(done):
                try:
                    outs[k] = cm.outputs(tt[k], yy[k], p)
                except LagcodegenError:
                    break
    status = int(getattr(soln, "status", 0))
    # scikit-sundae reports no step count, and nfev omits difference-quotient Jacobian calls.
    stats = dict(steps=None, rhs_evals=int(getattr(soln, "nfev", -1)),
                 jac_evals=int(getattr(soln, "njev", -1)), t_reached=float(soln.t[-1]) if done else float(t[0]),
                 model_error=state["model_error"])
    message = str(getattr(soln, "message", ""))
    if status < 0 or not getattr(soln, "success", True):
        status = status if status < 0 else -3
        message = _message(status, state["model_error"], message)
        if state["model_error"]:
            stats["t_reached"] = state["t"]
    return Result(t=np.asarray(soln.t, dtype=float), y=y, state_names=list(cm.state_names),
                  outputs={k: outs[:, i] for i, k in enumerate(cm.output_names)}, stats=stats,
                  status=status if status < 0 else 0, message=message if status < 0 else "success",
                  backend="sksundae", method=method)
