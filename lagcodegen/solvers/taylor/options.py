"""The Taylor family's options object (:class:`Taylor`): its values checked once, resolved into
what the Taylor runtime's driver takes (:mod:`.run`, :mod:`.ensemble`)."""

from __future__ import annotations

from dataclasses import dataclass

from ...errors import LagcodegenError
from ...result import Result
from ..family import Family
from .ensemble import run_taylor_ensemble
from .run import run_taylor
from .stepper import TaylorStepper


@dataclass(frozen=True, kw_only=True)
class Taylor(Family):
    """The generated Taylor-series integrator of a scene (libm only, no SUNDIALS; the model's jet
    built on first use): ``order`` of the series (None: from the tolerance, about
    -ln(rtol)/2 + 3); ``max_events``: events kept in a run. It needs no Jacobian, so
    ``jacobian=`` beside ``method="taylor"`` has no effect."""

    name = "Taylor"
    methods = ("taylor",)
    faces = ("ode",)
    ignores = ("jacobian",)

    order: int | None = None
    max_events: int = 10_000

    def __post_init__(self):
        super().__post_init__()
        if self.order is not None and not (isinstance(self.order, int) and 2 <= self.order):
            raise LagcodegenError(f"Taylor order must be an integer >= 2, got {self.order!r}")

    def run_ode(self, cm, t, y, p, rtol: float, atol, events=()) -> Result:
        """A run of the ODE of ``cm`` (inputs checked by the face); ``events`` located on each
        step's polynomial."""
        return run_taylor(cm, t, y, p, rtol=rtol, atol=atol, max_step=self.max_step, max_steps=int(self.max_steps),
                          order=self.order, events=events, max_events=self.max_events, max_wall=float(self.max_wall))

    def stepper_ode(self, cm, mem, rtol: float, atol, events=()) -> TaylorStepper:
        """The C state of an integrator object on the ODE of ``cm`` (``mem`` = (t, y, p), checked by
        the face): the jet's storage and workspace made once (:mod:`.stepper`); ``events`` located
        on each step's polynomial; ``max_steps`` is the budget of one call."""
        return TaylorStepper(cm, mem, rtol=rtol, atol=atol, max_step=float(self.max_step),
                             max_steps=int(self.max_steps), order=self.order, events=tuple(events),
                             max_events=self.max_events, max_wall=float(self.max_wall))

    def run_ode_inputs(self, cm, t, y, p, rtol: float, atol, inputs) -> Result:
        """A run of the ODE of ``cm`` driven by the input tables ``inputs``: each input a cubic of t
        in the jet, the run split at the tables' breakpoints (:mod:`.inputs`)."""
        from .inputs import run_taylor_inputs
        return run_taylor_inputs(cm, t, y, p, inputs, rtol=rtol, atol=atol, max_step=self.max_step,
                                 max_steps=int(self.max_steps), order=self.order, max_wall=float(self.max_wall))

    def ensemble_ode(self, cm, t, Y, P, rtol, atol, *, threads, save, progress):
        """Members (rows of Y, P) of the ODE of ``cm`` in one call of ``lcg_taylor_solve_many``."""
        return run_taylor_ensemble(cm, t, Y, P, threads=threads, save=save, progress=progress, rtol=rtol, atol=atol,
                                   max_step=self.max_step, max_steps=self.max_steps, order=self.order,
                                   max_wall=self.max_wall)
