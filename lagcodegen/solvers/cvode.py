"""The native CVODE runner of compiled scenes: the generated C driver ``<prefix>_cvode_solve``
calls CVODE with no Python in the solver loop; one call integrates over all output times."""

from __future__ import annotations

import numpy as np

from ..errors import LagcodegenError
from ..formulation.scene import band_order
from ..formulation.scene import bandwidths as widths
from ..result import Result
from .base import METHODS, message


def band_widths(cm, bandwidths=None, y=None, p=None) -> tuple[int, int]:
    """(upper, lower) bandwidths of the band solver for ``cm``: ``bandwidths`` if given, else
    from the scene's Jacobian pattern in the interleaved order (:func:`scene.band_order`); a
    module without a recorded pattern (e.g. Fortran) is probed numerically at ``y``."""
    if bandwidths is not None:
        mu, ml = (int(b) for b in bandwidths)
        if not (0 <= mu < cm.ny and 0 <= ml < cm.ny):
            raise LagcodegenError(f"bandwidths must lie in [0, {cm.ny - 1}], got {bandwidths!r}")
        return mu, ml
    pattern = getattr(cm.code, "jac_pattern", None)
    if pattern is None:
        pattern = _probe_pattern(cm, y, p)
    return widths(pattern, band_order(cm.n, cm.code.nz))


def _probe_pattern(cm, y, p) -> np.ndarray:
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


def solve_native(cm, t, y0, p, method, rtol, atol, jacobian, max_steps, first_step, max_step,
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
                  stats=stats, status=int(flag), message=message(flag, st.model_error, detail),
                  backend="native", method=method)


