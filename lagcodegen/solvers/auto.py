"""``method="auto"``: the Taylor method or Adams, chosen by the model's size and, where the size
rule would pick Taylor, by the model's measured costs.

One job: the rule. The size rule (:func:`size_rule`) picks Taylor for small models only (it was
measured on n-link pendulums); a model it would run on Taylor is then checked against its own
measured costs (:class:`MethodCosts`: an Adams run's time per right-hand side evaluation, its own
work included, and one Taylor step at the run's order, in seconds, measured on the compiled model
by :func:`lagcodegen.solvers.taylor.probe.measure_costs` and kept with it): Taylor is kept only if
its step costs less than what Adams spends over the interval of one Taylor step,

    taylor_step  <  E(rtol) * adams_evaluation,

with E(rtol) the right-hand side evaluations of Adams per Taylor step over the same interval
(:func:`adams_evaluations_per_taylor_step`, from runs of both methods). E is the lower envelope
of what was measured, so the rule errs towards Adams: it does not keep Taylor where Adams is
cheaper by these measures. Models with generalized speeds stay on Adams
(their size is infinite, :attr:`lagcodegen.simulation.ode.CompiledModel.method_size`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

#: ``method="auto"`` integrates models with at most this many coordinates by the Taylor method
#: (see :func:`size_rule`), and up to AUTO_TAYLOR_TIGHT_MAX_N at tight tolerances (rtol <= 1e-8).
AUTO_TAYLOR_MAX_N = 5
AUTO_TAYLOR_TIGHT_MAX_N = 10

#: Right-hand side evaluations of Adams (CVODE) per step of the Taylor method over the same
#: interval, against -log10(rtol), at rtol = atol: the smallest ratio measured over the planar
#: 1-, 3- and 5-link pendulums (q0 = 1 rad; with and without their Jacobian) and random 4- and
#: 8-joint spatial chains (benchmarks/multibody.py's ``chain``) over t in [0, 10] (``python
#: benchmarks/taylor_trees.py --evaluations``, its last line). Between the points
#: linear in log10(rtol), outside them the nearest.
EVALUATIONS = ((3.0, 1.27), (4.0, 1.93), (6.0, 3.44), (9.0, 6.99), (12.0, 11.87), (14.0, 15.61))


@dataclass(frozen=True)
class MethodCosts:
    """Measured costs of a compiled model, in seconds: ``adams_evaluation`` an Adams run's time
    per evaluation of the right-hand side (the evaluation and Adams's own work per step),
    ``taylor_step`` one step of its Taylor integrator at the order the run's tolerance sets (jet,
    step size and the state's update)."""

    adams_evaluation: float
    taylor_step: float


def adams_evaluations_per_taylor_step(rtol: float) -> float:
    """E(rtol): Adams's right-hand side evaluations per Taylor step (:data:`EVALUATIONS`)."""
    digits = -math.log10(rtol) if rtol > 0 else EVALUATIONS[-1][0]
    points = EVALUATIONS
    if digits <= points[0][0]:
        return points[0][1]
    for (d0, e0), (d1, e1) in zip(points, points[1:]):
        if digits <= d1:
            return e0 + (e1 - e0) * (digits - d0) / (d1 - d0)
    return points[-1][1]


def size_rule(n: float, rtol: float) -> str:
    """Taylor for up to :data:`AUTO_TAYLOR_MAX_N` coordinates at any tolerance, and up to
    :data:`AUTO_TAYLOR_TIGHT_MAX_N` at rtol <= 1e-8; Adams otherwise.

    Measured with ``python benchmarks/taylor.py --rounds 3`` (n-link pendulums, q0 = 0.1 and 1.0,
    t in [0, 10], time of ``simulate()`` at equal achieved error): Adams/Taylor time ratio 1.7-12
    for n <= 3, 1.0-2.1 at n = 5, 0.7-0.9 at n = 10 for errors >= 1e-6 but 1.0-1.7 below 1e-8,
    0.4-1.3 at n = 20 (Adams faster in most cells)."""
    if n <= AUTO_TAYLOR_MAX_N or (n <= AUTO_TAYLOR_TIGHT_MAX_N and rtol <= 1e-8):
        return "taylor"
    return "adams"


def by_costs(costs: MethodCosts, rtol: float) -> str:
    """"taylor" if a Taylor step costs less than Adams's evaluations over the same interval
    (``costs.taylor_step < E(rtol) costs.adams_evaluation``), else "adams"."""
    adams = adams_evaluations_per_taylor_step(rtol) * costs.adams_evaluation
    return "taylor" if costs.taylor_step < adams else "adams"


def choose_method(n: float, rtol: float, costs: Callable[[float], MethodCosts | None] | None = None) -> str:
    """The method ``method="auto"`` picks for a model of size ``n`` (its coordinates; infinite
    for generalized speeds) at ``rtol``: the size rule's (:func:`size_rule`), and where that is
    Taylor and ``costs`` (rtol -> the model's :class:`MethodCosts`, or None where they cannot be
    measured) gives the model's costs, Taylor only if they say so (:func:`by_costs`)."""
    method = size_rule(n, rtol)
    if method != "taylor" or costs is None:
        return method
    measured = costs(rtol)
    return method if measured is None else by_costs(measured, rtol)
