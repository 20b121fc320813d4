"""The IDA family's options object (:class:`IDA`): its values checked once, resolved into what the
native GGL driver (:mod:`.native`, :mod:`.ensemble`) or scikit-sundae's IDA takes."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import LagcodegenError
from ...result import Result
from ...util import check_finite
from ..base import _DOUBLE, tolerances
from ..family import Family, choice, combinations
from . import ensemble, native
from ..request import GGLForm, Recording, StepControl, remembered
from .native import ALGEBRAIC_ATOL
from .stepper import IDAStepper

BACKENDS = ("native", "sksundae")


@dataclass(frozen=True, kw_only=True)
class IDA(Family):
    """IDA (variable-order BDF) on the stabilized index-2 GGL form of a constrained system
    (eq. 4.5; unknowns q, v, lambda, mu).

    ``suppress_alg``: leave lambda, mu out of the error test (native); ``jacobian``: the
    generated residual Jacobian (None: when compiled) or difference quotients (False);
    ``alg_atol``: absolute tolerance of lambda, mu (None: :data:`~.native.ALGEBRAIC_ATOL`);
    ``stop_at_outputs``: step exactly to every output time (native); ``backend`` "native" or
    "sksundae"; ``max_order``, ``first_step``, ``min_step`` (0: IDA's); ``max_events`` (events
    kept; None: 10000 in a run, 64 per ensemble member).
    """

    name = "IDA"
    methods = ("bdf",)
    faces = ("ggl",)

    backend: str = "native"
    suppress_alg: bool = True
    jacobian: bool | None = None
    alg_atol: float | None = None
    stop_at_outputs: bool = False
    max_order: int = 0
    first_step: float = 0.0
    min_step: float = 0.0
    max_events: int | None = None

    def __post_init__(self):
        super().__post_init__()
        choice("backend", self.backend, BACKENDS)
        if self.alg_atol is not None:
            check_finite(self.alg_atol, "alg_atol")
        if self.max_wall and self.backend != "native":
            raise LagcodegenError("max_wall needs backend='native'")

    def _jacobian(self, sim) -> bool:
        jacobian = sim.info.ggl_jac if self.jacobian is None else bool(self.jacobian)
        if jacobian and not sim.info.ggl_jac:
            raise LagcodegenError("jacobian=True but the residual Jacobian was not generated "
                                  "(compile_constrained(..., jacobian=False))")
        return jacobian

    def tolerances(self, sim, rtol, atol):
        """(rtol, atol of every unknown q, v, lambda, mu): lambda, mu get ``alg_atol`` unless
        ``atol`` gives them; the array of a scalar ``atol`` is kept (read-only) on ``sim`` for the
        next call with the same value."""
        ng = sim.info.ng
        cached = sim.ggl_atol_cache
        if (type(atol) is float and self.alg_atol is None and type(rtol) is float and 0 < rtol < math.inf
                and cached[0] == _DOUBLE(atol)):
            return rtol, cached[1]  # what tolerances() gave for this atol last time
        rtol, atol_arr = tolerances(rtol, atol, ng, sim.ny)
        if np.asarray(atol).size != ng:  # lambda, mu: see ALGEBRAIC_ATOL
            atol_arr[sim.ny:] = ALGEBRAIC_ATOL if self.alg_atol is None else check_finite(self.alg_atol, "alg_atol")
            if type(atol) is float and self.alg_atol is None:  # kept (read-only) for the next call
                atol_arr.flags.writeable = False
                sim.ggl_atol_cache = (_DOUBLE(atol), atol_arr)
        return rtol, atol_arr

    def run_ggl(self, sim, t, yy0, yp0, p, rtol, atol, roots: bool) -> Result:
        """A GGL run of ``sim`` from the consistent initial values (yy0, yp0)."""
        jacobian = self._jacobian(sim)
        rtol, atol_arr = self.tolerances(sim, rtol, atol)
        # the records made once while the values stay the same: atol by identity, a read-only array
        # (the tolerances cached per model) that the records keep alive
        key = None if atol_arr.flags.writeable else (rtol, id(atol_arr), bool(jacobian), bool(roots))
        control, form, recording = remembered(self, key, lambda: (
            StepControl.of(self, rtol, atol_arr, method="bdf", jacobian=bool(jacobian)), self.ggl_form(),
            self.recording(10_000, roots=bool(roots))))
        if self.backend == "native":
            return native.solve_ggl(sim, t, yy0, yp0, p, control, form, recording)
        from .. import sksundae
        return sksundae.solve_ggl(sim, t, yy0, yp0, p, control, roots)

    def stepper_ggl(self, sim, mem, yy0, yp0, rtol, atol, roots: bool) -> IDAStepper:
        """The C state of an integrator object on the GGL form of ``sim`` (``mem`` = (t, y, p), the
        unknowns' initial values (yy0, yp0); checked by the face): IDA memory made once
        (:mod:`.stepper`); ``max_steps`` is the budget of one call."""
        if self.backend != "native":
            raise LagcodegenError("the integrator object runs on the native driver (backend='native')")
        jacobian = self._jacobian(sim)
        rtol, atol_arr = self.tolerances(sim, rtol, atol)
        control = StepControl.of(self, rtol, atol_arr, method="bdf", jacobian=bool(jacobian))
        return IDAStepper(sim, mem, yy0, yp0, control, self.ggl_form(), self.recording(10_000, roots=roots))

    def ensemble_ggl(self, sim, t, Y, P, rtol, atol, roots: bool, *, threads, save, progress):
        """Members (rows (yy0, yp0) of Y) of the GGL form of ``sim`` in one native call."""
        if self.backend != "native":
            raise LagcodegenError("ensembles run on the native drivers (backend='native')")
        jacobian = self._jacobian(sim)
        rtol_, atol_arr = self.tolerances(sim, rtol, atol)
        control = StepControl.of(self, rtol_, atol_arr, method="bdf", jacobian=jacobian)
        recording = self.recording(64, roots=roots, save=save, threads=threads, progress=progress)
        return ensemble.ensemble_ggl(sim, t, Y, P, control, self.ggl_form(), recording)

    # ------------------------------------------------------------------ the one entry (Family.run)
    def _ggl_run(self, pr, rq) -> Result:
        if rq.contacts is not None:  # the simulation's GGL impact driver (.constrained_impacts)
            return pr.sim.run_contacts(self, pr.t, pr.y, pr.p, pr.rtol, pr.atol, rq.roots, rq.contacts,
                                       cancel=rq.cancel)
        return self.run_ggl(pr.sim, pr.t, pr.y, pr.yp, pr.p, pr.rtol, pr.atol, rq.roots)

    def _ggl_stepper(self, pr, rq):
        if rq.contacts is not None:  # each propagate call one run of the GGL impact driver (.impact_stepper)
            return pr.sim.contact_stepper(self, pr.y, pr.rtol, pr.atol, rq.roots, rq.contacts)
        mem, (yy0, yp0) = pr.y, pr.yp
        return self.stepper_ggl(pr.sim, mem, yy0, yp0, pr.rtol, pr.atol, rq.roots)

    def _ggl_ensemble(self, pr, rq):
        m = rq.members
        return self.ensemble_ggl(pr.sim, pr.t, pr.y, pr.p, pr.rtol, pr.atol, rq.roots, threads=m.threads,
                                 save=m.save, progress=m.progress)

    #: What IDA runs (Family.run), declared once: every other combination is refused by name.
    runs = {
        ("ggl", "run"): (_ggl_run, combinations("", "events", "impacts", "events+impacts")),
        ("ggl", "stepper"): (_ggl_stepper, combinations("", "events", "impacts", "events+impacts")),
        # the ensembles of a system with contacts are its members' runs, each through ("ggl", "run")
        ("ggl", "ensemble"): (_ggl_ensemble, combinations("", "events")),
    }

    def ggl_form(self) -> GGLForm:
        """The GGL form of this object's runs (``suppress_alg``, ``stop_at_outputs``)."""
        return GGLForm(suppress_alg=bool(self.suppress_alg), stop_at_outputs=bool(self.stop_at_outputs))

    def recording(self, default_max_events: int, **values) -> Recording:
        """What a run records: ``values`` (roots, ...) and at most ``max_events`` events (None:
        ``default_max_events``)."""
        return Recording(max_events=default_max_events if self.max_events is None else self.max_events, **values)
