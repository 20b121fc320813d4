"""The Taylor family's runner: ``simulate(method="taylor")`` on a compiled scene: the Taylor integrator of the scene is built
on first use (per set of events) and kept with the compiled model."""

from __future__ import annotations

import numpy as np

from ...codegen.record import scene_of_code
from ...result import Result
from .runner import TaylorModule, build_taylor


def scene_of(cm):
    """The scene ``cm`` was generated from (the Taylor integrator is generated from it);
    LagcodegenError if ``cm`` has none (unpickled, or assembled by hand)."""
    return scene_of_code(cm.code, "method='taylor'")


def taylor_module(cm, events=()):
    """The compiled Taylor integrator of ``cm``'s scene with ``events`` (built once, then reused)."""
    return cm.artifacts.get(TaylorModule, ("events", tuple(events)),
                            lambda: build_taylor(scene_of(cm), events=events))


def run_taylor(cm, t: np.ndarray, y: np.ndarray, p: np.ndarray, *, rtol: float, atol: np.ndarray,
               max_step: float, max_steps: int, order: int | None, events=(), max_events: int = 10_000,
               max_wall: float = 0.0) -> Result:
    """Integrate with the Taylor method; the inputs were checked by the caller."""
    module = taylor_module(cm, events)
    return module.simulate(t, y, p, rtol=rtol, atol=atol, max_step=float(max_step), max_steps=max_steps,
                           order=order, max_events=max_events, max_wall=max_wall)
