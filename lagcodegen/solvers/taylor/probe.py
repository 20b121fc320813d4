"""The measured costs ``method="auto"`` weighs (:class:`lagcodegen.solvers.auto.MethodCosts`): an
Adams run's time per right-hand side evaluation and one step of the Taylor integrator of a compiled
model, timed on the model itself (some tens of milliseconds; the Taylor integrator is built for it,
as a Taylor run would).

One job: the measurement; the rule is :mod:`lagcodegen.solvers.auto`'s.
"""

from __future__ import annotations

import math
import time

import numpy as np

# --- the rest of lagcodegen: the one place to repoint when modules move -------------------
from ...codegen.taylor.emit import P_MAX
from ...errors import LagcodegenError
from ..auto import MethodCosts
# ------------------------------------------------------------------------------------------
from .run import taylor_module

#: Time spent on each of the two measurements at most (about: the last batch may run over).
BUDGET = 0.01

#: Steps per probe run at most: Taylor's, Adams's (a run's own Python, some ten microseconds,
#: is spread over them).
MAX_TAYLOR_STEPS = 256
MAX_ADAMS_STEPS = 4096


def run_order(rtol: float) -> int:
    """The Taylor order of a run at ``rtol`` (the driver's rule, lagcodegen/runtime/lcg_taylor_driver.h
    ``tl_order``: ceil(-ln(rtol)/2 + 3) within 2..P_MAX)."""
    order = math.ceil(-0.5 * math.log(rtol) + 3.0) if rtol > 0 else P_MAX
    return min(max(order, 2), P_MAX)


def probe_state(cm) -> np.ndarray:
    """A state to time the model at: the neutral coordinates plus 0.1, speeds 0.1 (the costs
    hardly depend on the values; a state at rest in the neutral configuration might take
    shortcuts)."""
    q = np.asarray(cm.code.q_neutral if cm.code.q_neutral is not None else np.zeros(cm.n), dtype=float) + 0.1
    return np.concatenate([q, np.full(cm.nv, 0.1), np.zeros(cm.ny - cm.n - cm.nv)])


def _best(run, budget: float, most: int) -> float:
    """The least CPU seconds (of the calling thread, which runs the integrators: a loaded machine's
    preemption does not count) per unit of ``run(k) -> units done`` over calls of ``k`` = 1, 2, 4, ...
    (the first call, which may load and warm what the run uses, left out), until a call takes
    ``budget`` / 8 or ``k`` reaches ``most``, and then while ``budget`` seconds are not spent
    (at most 32 calls)."""
    best, k, spent, calls = math.inf, 1, 0.0, 0
    while calls < 32:
        start = time.thread_time()
        units = run(k)
        elapsed = time.thread_time() - start
        spent += elapsed
        calls += 1
        if units > 0 and calls > 1:
            best = min(best, elapsed / units)
        if elapsed < budget / 8 and k < most:
            k *= 2
        elif spent >= budget and calls > 2:
            break
    return best


def measure_costs(cm, rtol: float, *, budget: float = BUDGET) -> MethodCosts | None:
    """The costs of ``cm`` (a :class:`lagcodegen.simulation.ode.CompiledModel`) at ``rtol``: an
    Adams run's time per right-hand side evaluation (its own work per step included) and one
    step of its Taylor integrator at the order ``rtol`` sets, each from runs of a growing number
    of steps from :func:`probe_state` (the least time per unit within ``budget`` seconds). None
    where either cannot run (no scene, an expression without a Taylor recurrence, a failing
    right-hand side)."""
    try:
        module = taylor_module(cm)
    except LagcodegenError:  # the Taylor method cannot run here: the caller's rule decides
        return None
    y = probe_state(cm)
    p = np.asarray(cm.code.param_defaults, dtype=float)
    t_out = np.array([0.0, 1e6])

    def adams(k):
        res = cm.simulate(t_out, y0=y, method="adams", rtol=rtol, atol=rtol,
                          max_steps=16 * k, raise_on_error=False)
        return int(res.stats.get("rhs_evals", 0))

    def steps(k):
        res = module.simulate(t_out, y, p, rtol=rtol, atol=rtol, max_steps=k)
        return int(res.stats.get("steps", 0))
    try:
        adams_cost = _best(adams, budget, MAX_ADAMS_STEPS // 16)
        step_cost = _best(steps, budget, MAX_TAYLOR_STEPS)
    except LagcodegenError:
        return None
    if not (math.isfinite(adams_cost) and math.isfinite(step_cost)):
        return None
    return MethodCosts(adams_evaluation=adams_cost, taylor_step=step_cost)
