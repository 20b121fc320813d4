"""What every solver family shares: the methods, the options check, the table of flag
messages, the initial state."""

from __future__ import annotations

import numpy as np

from ..errors import LagcodegenError, SingularMassMatrixError
from ..util import state_vector


METHODS = {"adams": 1, "bdf": 2}


LINEAR_SOLVERS = ("dense", "band", "fixedpoint")


def initial_state(cm, q0, v0, y0, z0=None) -> np.ndarray:
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


CVODE_FLAG_TEXT = {
    -1: "too many steps (max_steps reached); raise max_steps or loosen the tolerances",
    -2: "tolerance too tight for machine precision",
    -3: "error test failed repeatedly or with |h| = hmin",
    -4: "corrector convergence failed repeatedly",
    -8: "the right-hand side failed unrecoverably",
    -9: "the right-hand side failed at the first call",
    -10: "the right-hand side failed repeatedly with recoverable errors (non-finite values)",
}


def message(flag: int, model_error: int, detail: str) -> str:
    if flag >= 0:
        return "success"
    if model_error == 1:
        return "the mass matrix is singular"
    if model_error == 2:
        return "a computed value is not finite"
    text = CVODE_FLAG_TEXT.get(flag, f"CVODE failed with flag {flag}")
    return f"{text}: {detail}" if detail else text


def check_initial_mass_matrix(cm, t0: float, y: np.ndarray, p: np.ndarray) -> None:
    """Raise SingularMassMatrixError naming the state if M is singular at (t0, y)."""
    try:
        cm.rhs(t0, y, p)
    except SingularMassMatrixError as exc:
        raise SingularMassMatrixError(
            "the mass matrix is singular at the initial state "
            f"({', '.join(f'{k}={v:g}' for k, v in zip(cm.state_names, y))})", t=float(t0)) from exc


