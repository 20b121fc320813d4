"""Forward sensitivities on the Taylor integrator of runs driven by input tables (the variational
jet of the inputs' cubics, segment by segment): the forced damped oscillator of
test_sensitivity_inputs.py, its states and sensitivities to k, c and x(0) against CVODE's
input-driven sensitivity run, against a second integrator of the variational equations (DOP853
on the augmented ODE), dx/dx(0) against its closed form (central differences of plain Taylor
table-driven runs: test_sensitivity_inputs.py, parametrized by family); a table that jumps (zero-order hold); a direction along the input
refused; a run stopped by its step budget keeps its rows and their sensitivities together.
Ensembles driven by tables with sensitivities, on CVODE and Taylor: each member bit-identical to
its run alone."""

import sys
from pathlib import Path

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen.errors import LagcodegenError

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_sensitivity_inputs import (DIRECTIONS, K, TIMES, VALUES, X0,  # noqa: E402
                                     free_response, variational_reference)
from test_sensitivity_inputs import sim, table  # noqa: E402,F401 (the fixtures: the oscillator compiled, its table)

TIGHT = dict(rtol=1e-12, atol=1e-14)


def test_taylor_sensitivities_of_a_table_driven_run(sim, table):
    t = np.linspace(0.0, 8.0, 161)
    res = sim.simulate(t, q0=[X0], inputs={"F": table}, method="taylor", sensitivities=DIRECTIONS, **TIGHT)
    assert res.success and res.method == "taylor" and res.stats["restarts"] == 3  # the kinks at 1, 2.5, 4
    assert res.sensitivities.shape == (t.size, 3, 4) and res.sensitivity_names == DIRECTIONS
    assert res.stats["steps"] > 4 and res.stats["jet_evals"] >= res.stats["steps"]
    # CVODE's input-driven sensitivity run (lcg_cvsens_solve_inputs), a different integrator
    cv = sim.simulate(t, q0=[X0], inputs={"F": table}, sensitivities=DIRECTIONS, **TIGHT)
    assert np.array_equal(res.t, cv.t)
    assert np.max(np.abs(res.y - cv.y)) < 1e-7 * np.max(np.abs(cv.y))
    for j, name in enumerate(DIRECTIONS):
        for value in ("x", "x_dot", "spring"):
            a, b = res.sensitivity(value, name), cv.sensitivity(value, name)
            assert np.max(np.abs(a - b)) < 1e-7 * np.max(np.abs(b)), (name, value)
    # DOP853 on the augmented ODE, restarted at the kinks, and the closed form of dx/dx(0)
    x_ref, s_ref = variational_reference(t, table)
    assert np.max(np.abs(res["x"] - x_ref)) < 1e-9
    assert np.max(np.abs(res.sensitivities[:, :, 0] - s_ref)) < 1e-9 * np.max(np.abs(s_ref))
    assert np.max(np.abs(res.sensitivity("x", "x(0)") - free_response(t))) < 1e-9
    # the outputs: the force is the table and depends on no direction; d(k x)/dk = x + k dx/dk
    assert np.allclose(res["force"], table(t), rtol=0, atol=1e-13)
    assert np.all(res.sensitivity("force", "k") == 0.0)
    assert np.max(np.abs(res.sensitivity("spring", "k") - (res["x"] + K * res.sensitivity("x", "k")))) < 1e-12
    # the forced run differs from the free one: the table does act in the sensitivity run
    free = sim.simulate(t, q0=[X0], method="taylor", sensitivities=["k"], **TIGHT)
    assert np.max(np.abs(free.sensitivity("x", "k") - s_ref[:, 0])) > 0.1


def test_output_times_on_and_off_the_breakpoints(sim, table):
    t = np.array([0.0, 1.0, 1.7, 2.5, 3.2, 4.0, 7.0])
    res = sim.simulate(t, q0=[X0], inputs={"F": table}, method="taylor", sensitivities=DIRECTIONS, **TIGHT)
    x_ref, s_ref = variational_reference(t, table)
    assert np.array_equal(res.t, t)
    assert np.max(np.abs(res["x"] - x_ref)) < 1e-9
    assert np.max(np.abs(res.sensitivities[:, :, 0] - s_ref)) < 1e-9 * np.max(np.abs(s_ref))


def test_a_table_that_jumps(sim):
    """A zero-order-hold force: u jumps at each breakpoint, x and s stay continuous (the jump
    times do not depend on the directions); Taylor and CVODE agree."""
    zoh = lcg.Table(TIMES, VALUES, kind="zoh")
    t = np.linspace(0.0, 7.0, 71)
    res = sim.simulate(t, q0=[X0], inputs={"F": zoh}, method="taylor", sensitivities=DIRECTIONS, **TIGHT)
    cv = sim.simulate(t, q0=[X0], inputs={"F": zoh}, sensitivities=DIRECTIONS, **TIGHT)
    assert res.success and np.allclose(res["force"], zoh(t), rtol=0, atol=0)
    assert np.max(np.abs(res.sensitivities - cv.sensitivities)) < 1e-7 * np.max(np.abs(cv.sensitivities))


def test_refusal_and_step_budget(sim, table):
    t = np.linspace(0.0, 6.0, 13)
    with pytest.raises(LagcodegenError, match="'F' is an input driven by a table"):
        sim.simulate(t, q0=[X0], inputs={"F": table}, method="taylor", sensitivities=["k", "F"])
    # without a table F is a run-time parameter: d x/d F of a constant force; that call, learned by
    # simulate()'s fast path, is not taken for the same call with a table (refused again)
    res = sim.simulate(t, q0=[X0], method="taylor", sensitivities=["F"], **TIGHT)
    assert np.max(np.abs(res.sensitivity("x", "F") - (1 - free_response(t)) / K)) < 1e-10
    again = sim.simulate(t, q0=[X0], method="taylor", sensitivities=["F"], **TIGHT)
    assert np.array_equal(again.sensitivities, res.sensitivities)
    with pytest.raises(LagcodegenError, match="'F' is an input driven by a table"):
        sim.simulate(t, q0=[X0], method="taylor", sensitivities=["F"], inputs={"F": table}, **TIGHT)
    # a step budget used up in the third segment: the rows reached with their sensitivities
    full = sim.simulate(t, q0=[X0], inputs={"F": table}, method="taylor", sensitivities=["k"], **TIGHT)
    part = sim.simulate(t, q0=[X0], inputs={"F": table}, method="taylor", sensitivities=["k"],
                        max_steps=full.stats["steps"] // 2, raise_on_error=False, **TIGHT)
    assert part.status < 0 and 0 < part.t.size < t.size
    assert part.sensitivities.shape == (part.t.size, 1, 4)
    assert np.array_equal(part.sensitivities, full.sensitivities[:part.t.size])


@pytest.mark.parametrize("method,threads", [("adams", 1), ("adams", 2), ("taylor", 1), ("taylor", 2)])
def test_ensemble_members_bit_identical_to_single_runs(sim, table, method, threads):
    """Ensembles with input tables and sensitivities (CVODE and Taylor): member i, driven by its
    own table, has the states and sensitivities of its run alone, bit for bit."""
    t = np.linspace(0.0, 6.0, 31)
    other = lcg.Table(TIMES, [0.0, -1.0, 0.5, 0.0, 2.0], kind="cubic")
    tables = [table, other, table]
    q0 = np.array([[X0], [0.0], [-0.2]])
    ks = np.array([K, 3.0, 5.0])
    opts = dict(method=method, rtol=1e-10, atol=1e-12)
    ens = sim.ensemble(t, q0=q0, params={"k": ks}, inputs={"F": tables}, save="trajectory", threads=threads,
                       sensitivities=DIRECTIONS, **opts)
    assert np.all(ens.status == 0) and ens.method == method
    assert ens.sensitivity_trajectories.shape == (3, t.size, 3, 4)
    for i in range(3):
        alone = sim.simulate(t, q0=q0[i], params={"k": ks[i]}, inputs={"F": tables[i]}, sensitivities=DIRECTIONS,
                             **opts)
        assert np.array_equal(ens.sensitivity_trajectories[i], alone.sensitivities)
        assert np.array_equal(ens.sensitivities[i], alone.sensitivities[-1])
        assert np.array_equal(ens["x"][i], alone["x"])
        assert ens.stats["steps"][i] == alone.stats["steps"] > 0
    # an independent fact: member 0 is the run of the DOP853 reference
    x_ref, s_ref = variational_reference(t, table)
    assert np.max(np.abs(ens.sensitivity_trajectories[0][:, :, 0] - s_ref)) < 1e-7 * np.max(np.abs(s_ref))
    with pytest.raises(LagcodegenError, match="'F' is an input driven by a table"):
        sim.ensemble(t, q0=q0, inputs={"F": tables}, sensitivities=["F"], method=method)
