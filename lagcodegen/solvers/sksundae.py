"""scikit-sundae's Python API on the compiled functions (one Python callback per right-hand
side evaluation, about 5 us each): the second method that checks the native drivers."""

from __future__ import annotations

import numpy as np

from ..errors import LagcodegenError
from ..result import Result
from .base import message


def solve_sksundae(cm, t, y0, p, method, rtol, atol, jacobian, max_steps, first_step, max_step,
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
    text = str(getattr(soln, "message", ""))
    if status < 0 or not getattr(soln, "success", True):
        status = status if status < 0 else -3
        text = message(status, state["model_error"], text)
        if state["model_error"]:
            stats["t_reached"] = state["t"]
    return Result(t=np.asarray(soln.t, dtype=float), y=y, state_names=list(cm.state_names),
                  outputs={k: outs[:, i] for i, k in enumerate(cm.output_names)}, stats=stats,
                  status=status if status < 0 else 0, message=text if status < 0 else "success",
                  backend="sksundae", method=method)


