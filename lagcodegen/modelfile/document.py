"""A loaded model file, and how it runs.

One job: the result of loading. :class:`ModelFile` (the model, its [constraints] and
[[events]], its :class:`SimulationSettings`) runs what the file describes once compiled
(:func:`lagcodegen.compile_file`); :func:`constrained_outputs` and :func:`constrained_method`
say how a constrained run goes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ..derivation import derive
from ..errors import ModelError
from ..model.events import Event
from ..model.model import Model
from ..theory.constraints import ConstrainedSystem
from .locate import ModelFileError, _Locator

if TYPE_CHECKING:  # pragma: no cover
    from ..derivation import EquationsOfMotion
    from ..result import Result


@dataclass
class SimulationSettings:
    """The ``[simulation]`` table: how a build step should run the model."""

    t_start: float = 0.0
    t_end: float = 10.0
    n_out: int = 1001
    method: str = "adams"
    rtol: float = 1e-8
    atol: float = 1e-10
    max_steps: int | None = None  # the step budget of the whole run (None: the solvers' default)
    initial: dict[str, float] = field(default_factory=dict)
    outputs: list[str] = field(default_factory=list)
    runtime_parameters: list[str] | None = None
    parameters: dict[str, float] = field(default_factory=dict)
    jacobian: bool = True
    formulation: str | None = None  # constrained files: "index1" (default), "ggl" or "minimal"
    baumgarte: tuple[float, float] | str = "auto"  # index1: "auto" or (alpha, beta); (0, 0) is none
    projection: bool = False  # index1: project onto the constraints after each step (BDF)


@dataclass
class ModelFile:
    """A loaded model file: the model, its simulation settings and where it came from."""

    model: Model
    simulation: SimulationSettings
    path: Path
    source: str = field(default="", repr=False, compare=False)  # the TOML text, for error lines
    #: The model with the file's [constraints] (a ConstrainedSystem), or None without constraints.
    constrained: ConstrainedSystem | None = field(default=None, repr=False, compare=False)
    #: The file's [[events]] (Event items; the inequality constraints' events ineq_<k> come on top).
    events: list[Event] = field(default_factory=list, compare=False)

    def initial_state(self) -> tuple[list[float], list[float]]:
        """Initial coordinates and velocities from ``simulation.initial`` (missing entries 0.0; a
        quaternion's scalar part 1, :meth:`Model.neutral`); velocities per speed."""
        init = self.simulation.initial
        neutral = self.model.neutral()
        q0 = [float(init.get(q.name, x)) for q, x in zip(self.model.coords, neutral)]
        v0 = [float(init.get(v.name, 0.0)) for v in self.model.v]
        return q0, v0

    def times(self) -> np.ndarray:
        """Output times: ``n_out`` points evenly spaced from ``t_start`` to ``t_end``."""
        s = self.simulation
        return np.linspace(s.t_start, s.t_end, s.n_out)

    def derive(self) -> EquationsOfMotion:
        """:func:`lagcodegen.derive` of the model, with model errors located in this file."""
        try:
            return derive(self.model)
        except ModelFileError:
            raise
        except ModelError as exc:
            raise _Locator(self.source, str(self.path)).error(("model", "coordinates"), str(exc)) from None

    def simulate(self, compiled: Any, **options: Any) -> Result:
        """Run the simulation the file describes on ``compiled``, the model compiled with this
        file's settings (:func:`lagcodegen.compile_file`).

        Parameter overrides are passed for its run-time parameters only. Constrained files
        integrate with BDF where the formulation needs it (``ggl``, index-1 with projection),
        else with ``method``; the file's events (every kind of model) are located and found in
        ``Result.events``. ``options``
        (``method=...``, ``rtol=...``, ``backend=...``, ...) override.
        """
        cm = compiled
        s = self.simulation
        q0, v0 = self.initial_state()
        method = s.method
        if self.constrained is not None:
            method = constrained_method(getattr(cm, "formulation", s.formulation), getattr(cm, "projection", False),
                                        s.method)
        kwargs: dict[str, Any] = dict(
            q0=q0, v0=v0, method=method, rtol=s.rtol, atol=s.atol,
            params={k: v for k, v in s.parameters.items() if k in cm.param_names})
        if s.max_steps is not None:
            kwargs["max_steps"] = s.max_steps
        if self.constrained is None and self.events:  # compiled in for constrained files
            kwargs["events"] = list(self.events)
        kwargs.update(options)
        return cm.simulate(self.times(), **kwargs)


def constrained_outputs(system: ConstrainedSystem, requested: Sequence[str], formulation: str | None) -> list[str]:
    """Outputs of a constrained run: ``requested`` (default: energy) plus the multipliers
    (``lambda``, except in minimal coordinates, which have none), the constraint residuals
    (``residuals``) and, when there are inequality constraints, their values (``inequalities``)."""
    out = list(requested) if requested else ["energy"]
    extra = ["lambda"] if formulation != "minimal" and system.J else []
    extra.append("residuals")
    if system.inequalities:
        extra.append("inequalities")
    return out + [name for name in extra if name not in out]


def constrained_method(formulation: str | None, projection: bool, method: str) -> str:
    """The integration method of a constrained run: GGL (IDA) and index-1 with projection
    (CVODE projects with BDF only) use ``"bdf"``; otherwise ``method``."""
    if formulation == "ggl" or (formulation in (None, "index1") and projection):
        return "bdf"
    return method
