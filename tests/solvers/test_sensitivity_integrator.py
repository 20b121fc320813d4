"""The integrator object with forward sensitivities on CVODE (lcg_cvsens_stepper) and on the
Taylor method (the Taylor stepper on the variational jet): a fresh integrator's grid
bit-identical to simulate(..., sensitivities=...), the writable sensitivities restarting the run
as a new one would, events with their times' sensitivities (CVODE and Taylor)."""

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.errors import LagcodegenError

NAMES = ["l", "g", "theta(0)", "theta_dot(0)"]


@pytest.fixture(scope="module")
def pend():
    return lcg.compile_model(lcg.systems.pendulum(), outputs=["energy"])


def _states(res):
    """(nt, ny, ns): a run's sensitivities of the states, as the integrator gives them."""
    return res.sensitivities[:, :, :len(res.state_names)].transpose(0, 2, 1)


@pytest.mark.parametrize("method", ["adams", "bdf", "taylor"])
def test_fresh_grid_bit_identical_to_simulate(pend, method):
    t = np.linspace(0.0, 2.0, 41)
    ref = pend.simulate(t, q0=[0.5], v0=[0.2], params={"l": 1.3}, method=method, sensitivities=NAMES)
    integ = pend.integrator(q0=[0.5], v0=[0.2], params={"l": 1.3}, method=method, sensitivities=NAMES)
    assert integ.sensitivities.shape == (2, 4)
    assert np.array_equal(integ.sensitivities, [[0, 0, 1, 0], [0, 0, 0, 1]])
    y, S = integ.propagate_grid(t)
    assert np.array_equal(y, ref.y)
    assert np.array_equal(S, _states(ref))
    assert integ.time == 2.0 and np.array_equal(integ.state, ref.y[-1])
    assert np.array_equal(integ.sensitivities, _states(ref)[-1])
    assert integ.sensitivity("theta", "l") == ref.sensitivity("theta", "l")[-1]
    assert integ.stats["steps"] == ref.stats["steps"]


@pytest.mark.parametrize("method", ["adams", "taylor"])
def test_written_state_params_and_sensitivities_restart_as_a_new_run(pend, method):
    """After a first run, the state, a parameter and the sensitivities written: the next grid is
    the run simulate() makes from there, bit for bit; the views are the C memory's."""
    integ = pend.integrator(q0=[0.5], method=method, sensitivities=NAMES)
    integ.propagate_until(0.7)
    integ.time = 0.0
    integ.state[:] = [0.3, -0.1]
    integ.set_param("l", 0.9)
    assert integ.params[0] == 0.9 and list(integ.param_names).index("l") == 0
    integ.sensitivities = [[0, 0, 1, 0], [0, 0, 0, 1]]
    t = np.linspace(0.0, 1.0, 11)
    y, S = integ.propagate_grid(t)
    ref = pend.simulate(t, q0=[0.3], v0=[-0.1], params={"l": 0.9}, method=method, sensitivities=NAMES)
    assert np.array_equal(y, ref.y) and np.array_equal(S, _states(ref))
    assert np.array_equal(integ.state, ref.y[-1]) and np.array_equal(integ.sensitivities, _states(ref)[-1])
    # propagate_for and step go on from there with their sensitivities, finite and moving
    before = integ.sensitivities.copy()
    integ.propagate_for(0.1)
    assert integ.step() > 1.1 and np.all(np.isfinite(integ.sensitivities))
    assert not np.array_equal(before, integ.sensitivities)


def test_written_sensitivities_restart_as_a_new_run(pend):
    """At t = 1 the sensitivities are reset to those a run starts with: the rest of the grid is
    the run of simulate() from the state there, bit for bit; d theta(2) / d theta(1) from the
    reset agrees with the chain rule of the uninterrupted run: S(2, 0) = S(2, 1) S(1, 0)."""
    integ = pend.integrator(q0=[0.5], method="adams", sensitivities=NAMES)
    integ.propagate_until(1.0)
    S10 = integ.sensitivities.copy()
    y1 = integ.state.copy()
    integ.sensitivities[:] = 0.0
    integ.sensitivities[:, 2:] = np.eye(2)
    t2 = np.linspace(1.0, 2.0, 21)
    y, S = integ.propagate_grid(t2)
    ref = pend.simulate(t2, y0=y1, sensitivities=NAMES)
    assert np.array_equal(y, ref.y) and np.array_equal(S, _states(ref))
    # the chain rule against a run of its own from t = 0 (tolerance-level agreement)
    whole = pend.simulate(np.linspace(0.0, 2.0, 41), q0=[0.5], rtol=1e-10, atol=1e-12, sensitivities=NAMES)
    S20 = _states(whole)[-1]
    S21 = S[-1]
    chained = S21[:, 2:] @ S10[:, 2:]  # initial values: d y(2)/d y(1) d y(1)/d y(0)
    assert np.max(np.abs(chained - S20[:, 2:])) < 1e-5 * np.max(np.abs(S20[:, 2:]))
    params = S21[:, 2:] @ S10[:, :2] + S21[:, :2]  # parameters: through y(1) and directly
    assert np.max(np.abs(params - S20[:, :2])) < 1e-5 * np.max(np.abs(S20[:, :2]))


def test_until_step_and_events(pend):
    ev = lcg.Event("bottom", sp.Symbol("theta"), -1, True)
    integ = pend.integrator(q0=[0.5], method="adams", sensitivities=["l", "g"], events=[ev])
    t_step = integ.step()
    assert 0.0 < t_step < 0.5
    rec = integ.propagate_until(3.0)
    assert rec is integ.stopped_by and rec.name == "bottom"
    ref = pend.simulate(np.linspace(0.0, 3.0, 4), q0=[0.5], events=[ev], sensitivities=["l", "g"])
    # the quarter period scales as sqrt(l/g): dt/dl = t/(2 l), dt/dg = -t/(2 g)
    assert abs(rec.t_sensitivity["l"] - rec.t / 2.0) < 1e-6 * rec.t
    assert abs(rec.t_sensitivity["g"] + rec.t / (2 * 9.81)) < 1e-6 * rec.t
    assert abs(rec.t - ref.events[-1].t) < 1e-7
    assert integ.time == rec.t
    # the next call goes on from the event without finding it again
    integ.propagate_until(rec.t + 0.1)
    assert integ.stopped_by is None and integ.time == pytest.approx(rec.t + 0.1)


def test_taylor_until_and_events(pend):
    """The Taylor integrator object with events: the record of the terminal event with its time's
    sensitivities, the time and sensitivities there those of simulate(method="taylor")'s last row."""
    ev = lcg.Event("bottom", sp.Symbol("theta"), -1, True)
    tol = dict(rtol=1e-12, atol=1e-14)
    integ = pend.integrator(q0=[0.5], method="taylor", sensitivities=["l", "g"], events=[ev], **tol)
    rec = integ.propagate_until(3.0)
    assert rec is integ.stopped_by and rec.name == "bottom" and integ.time == rec.t
    ref = pend.simulate(np.linspace(0.0, 3.0, 4), q0=[0.5], events=[ev], sensitivities=["l", "g"], method="taylor",
                        **tol)
    assert abs(rec.t - ref.events[-1].t) < 1e-12
    # the quarter period scales as sqrt(l/g): dt/dl = t/(2 l), dt/dg = -t/(2 g)
    assert abs(rec.t_sensitivity["l"] - rec.t / 2.0) < 1e-9 * rec.t
    assert abs(rec.t_sensitivity["g"] + rec.t / (2 * 9.81)) < 1e-9 * rec.t
    assert np.max(np.abs(integ.sensitivities.T - ref.sensitivities[-1, :, :2])) < 1e-10
    # the next call goes on from the event without finding it again
    integ.propagate_until(rec.t + 0.1)
    assert integ.stopped_by is None and integ.time == pytest.approx(rec.t + 0.1)


def test_bad_input_is_named(pend):
    integ = pend.integrator(q0=[0.5], method="adams", sensitivities=["l"])
    with pytest.raises(LagcodegenError, match=r"sensitivities has shape \(3,\), expected \(2, 1\)"):
        integ.sensitivities = [1.0, 2.0, 3.0]
    with pytest.raises(LagcodegenError, match="non-finite"):
        integ.sensitivities = [[np.nan], [0.0]]
    with pytest.raises(LagcodegenError, match="not a sensitivity direction"):
        integ.sensitivity("theta", "g")
    with pytest.raises(LagcodegenError, match="time going backward"):
        integ.propagate_until(-1.0)
    with pytest.raises(LagcodegenError, match="linear_solver 'band'"):
        pend.integrator(q0=[0.5], method="bdf", linear_solver="band", sensitivities=["l"])
    integ.close()
    with pytest.raises(LagcodegenError, match="closed"):
        integ.propagate_grid([0.0, 1.0])


def test_stepper_compiles_strictly(tmp_path, cc):
    import subprocess

    from helpers import STRICT_CFLAGS
    from lagcodegen.runtime import sources as runtime_files
    from lagcodegen.solvers.cvode.sensitivity import _sources
    from lagcodegen.solvers.cvode.sensitivity_stepper import STEPPER_FILES
    for name, text in {**_sources(), **runtime_files(STEPPER_FILES)}.items():
        (tmp_path / name).write_text(text)
    proc = subprocess.run([cc, *STRICT_CFLAGS, "-O2", "-c", "lcg_cvsens_stepper.c", "-o", "stepper.o"],
                          cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    nm = subprocess.run(["nm", "stepper.o"], cwd=tmp_path, capture_output=True, text=True).stdout
    assert "lcg_cvsens_stepper_grid" in nm and "lcg_cvsens_solve_events" in nm
