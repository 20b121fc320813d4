"""Solver option objects: one per solver family, passed as ``simulate(..., solver=CVODE(...))``.

Each object holds the options that belong to its family (keyword-only, checked when made) and
expands into the keyword arguments of ``simulate``; a keyword given beside ``solver=`` must
not contradict it. The families and the runners that take them:

* :class:`CVODE`: native CVODE drivers (:mod:`.cvode`) or scikit-sundae (:mod:`.sksundae`);
* :class:`IDA`: the GGL form of constrained systems (:mod:`.ida`, :mod:`.sksundae`);
* :class:`Taylor`: the generated Taylor-series integrator (:mod:`.taylor`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from ..errors import LagcodegenError
from .base import LINEAR_SOLVERS, METHODS

BACKENDS = ("native", "sksundae")


@dataclass(frozen=True, kw_only=True)
class CVODE:
    """CVODE: ``method`` "adams" (nonstiff) or "bdf" (stiff); ``linear_solver`` "dense", "band"
    or "fixedpoint"; ``jacobian`` the generated one (None: when compiled) or difference quotients
    (False); ``bandwidths`` (upper, lower) of the band solver; ``max_order`` (0: CVODE's);
    ``backend`` "native" (generated driver) or "sksundae"."""

    method: str = "adams"
    linear_solver: str = "dense"
    jacobian: bool | None = None
    bandwidths: tuple[int, int] | None = None
    max_order: int = 0
    backend: str = "native"

    def __post_init__(self):
        _choice("method", self.method, tuple(METHODS))
        _choice("linear_solver", self.linear_solver, LINEAR_SOLVERS)
        _choice("backend", self.backend, BACKENDS)

    def keywords(self) -> dict:
        return asdict(self)


@dataclass(frozen=True, kw_only=True)
class IDA:
    """IDA on the GGL form: ``suppress_alg`` (leave lambda, mu out of the error test),
    ``jacobian`` (the generated residual Jacobian; None: when compiled), ``alg_atol`` (absolute
    tolerance of lambda, mu), ``stop_at_outputs`` (step to every output time), ``backend``."""

    suppress_alg: bool = True
    jacobian: bool | None = None
    alg_atol: float | None = None
    stop_at_outputs: bool = False
    backend: str = "native"

    def __post_init__(self):
        _choice("backend", self.backend, BACKENDS)

    def keywords(self) -> dict:
        return {**asdict(self), "method": "bdf"}


@dataclass(frozen=True, kw_only=True)
class Taylor:
    """The generated Taylor-series integrator: ``order`` of the series (None: from the
    tolerance, about -ln(rtol)/2 + 1)."""

    order: int | None = None

    def __post_init__(self):
        if self.order is not None and not (isinstance(self.order, int) and 2 <= self.order):
            raise LagcodegenError(f"Taylor order must be an integer >= 2, got {self.order!r}")

    def keywords(self) -> dict:
        return {"method": "taylor", "order": self.order}


def _choice(name: str, value, choices) -> None:
    if value not in choices:
        raise LagcodegenError(f"{name} must be one of {', '.join(map(str, choices))}, got {value!r}")


def merge(solver, given: dict, defaults: dict) -> dict:
    """The keyword arguments of a run: ``given`` (those the caller passed, with their values)
    completed by ``solver``'s; a keyword given both ways with different values is an error."""
    if solver is None:
        return given
    if not hasattr(solver, "keywords"):
        raise LagcodegenError(f"solver must be CVODE(...), IDA(...) or Taylor(...), got {solver!r}")
    out = dict(given)
    for key, value in solver.keywords().items():
        if key in given and given[key] != defaults.get(key) and given[key] != value:
            raise LagcodegenError(f"{key}={given[key]!r} contradicts solver={solver!r}")
        out[key] = value
    return out
