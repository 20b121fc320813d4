"""The C source of a scene's event functions (``<prefix>_events.c``: ``int
<prefix>_events(t, y, p, gout)``), printed from the events kernel
(:func:`lagcodegen.formulation.events.events_block`) by the C backend. A file of its own, compiled
into a small library per set of events beside the model's: the model's code does not change."""

from __future__ import annotations

from ..codes import ModelCode
from ..formulation.events import events_block, events_gradient_block
from ..formulation.scene import Scene
from ..model.events import Event
from ..version import __version__
from .c import print_block
from .templates import environment


def events_function(prefix: str) -> str:
    """The name of the event function of the scene with ``prefix``."""
    return f"{prefix}_events"


def events_source(scene: Scene, events: list[Event]) -> dict[str, str]:
    """``{"<prefix>_events.c": text}`` for the checked ``events`` of ``scene``
    (:func:`lagcodegen.formulation.events.scene_events`)."""
    crossing = {-1: "decreasing", 0: "either way", 1: "increasing"}
    described = [f"{ev.name} (crossing {crossing[ev.direction]}, {'terminal' if ev.terminal else 'not terminal'})"
                 for ev in events]
    text = environment().get_template("c/events.c.j2").render(
        prefix=scene.prefix, version=__version__, model_name=scene.eom.model.name, ne=len(events),
        described=described, nonfinite=int(ModelCode.NONFINITE), body=print_block(events_block(scene, events)))
    return {f"{scene.prefix}_events.c": text}


def events_gradient_function(prefix: str) -> str:
    """The name of the event functions' derivatives of the scene with ``prefix``."""
    return f"{prefix}_events_grad"


#: The C prototype of the event functions' derivatives (``{prefix}`` to fill in).
EVENTS_GRAD = "int {prefix}_events_grad(double t, const double *y, const double *p, double *gt, double *gy, double *gp)"


def events_gradient_source(scene: Scene, events: list[Event]) -> dict[str, str]:
    """``{"<prefix>_events_grad.c": text}``: dg/dt, dg/dy and dg/dp of the checked ``events`` of
    ``scene`` (:func:`lagcodegen.formulation.events.events_gradient_block`), for the sensitivities
    of the event times; a file of its own, compiled only for runs with sensitivities."""
    crossing = {-1: "decreasing", 0: "either way", 1: "increasing"}
    described = [f"{ev.name} (crossing {crossing[ev.direction]}, {'terminal' if ev.terminal else 'not terminal'})"
                 for ev in events]
    eom = scene.eom
    text = environment().get_template("c/events_grad.c.j2").render(
        prefix=scene.prefix, version=__version__, model_name=eom.model.name, ne=len(events),
        ny=(eom.model.n + eom.model.nv if eom.general else 2 * eom.model.n) + len(eom.quadratures),
        np=len(scene.runtime_parameters), described=described,
        nonfinite=int(ModelCode.NONFINITE), body=print_block(events_gradient_block(scene, events)))
    return {f"{scene.prefix}_events_grad.c": text}
