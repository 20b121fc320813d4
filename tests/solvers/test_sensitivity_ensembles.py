"""Forward sensitivities in ensembles (CVODE and Taylor): each member's states and sensitivities
bit-identical to the same run alone, and by member in the result."""

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen.errors import LagcodegenError


@pytest.fixture(scope="module")
def pend():
    return lcg.compile_model(lcg.systems.pendulum(), outputs=["energy"])


NAMES = ["l", "g", "theta(0)", "theta_dot(0)"]


@pytest.mark.parametrize("method,threads", [("adams", 1), ("adams", 2), ("taylor", 1), ("taylor", 2)])
def test_members_bit_identical_to_single_runs(pend, method, threads):
    t = np.linspace(0.0, 2.0, 41)
    q0 = np.array([[0.3], [1.0], [2.0]])
    ls = np.array([0.8, 1.0, 1.3])
    ens = pend.ensemble(t, q0=q0, params={"l": ls}, save="trajectory", threads=threads, sensitivities=NAMES,
                        method=method)
    assert ens.sensitivities.shape == (3, 4, 3)
    assert ens.sensitivity_trajectories.shape == (3, t.size, 4, 3)
    assert ens.sensitivity_names == NAMES and ens.sensitivity_values == ["theta", "theta_dot", "energy"]
    for i in range(3):
        alone = pend.simulate(t, q0=q0[i], params={"l": ls[i]}, sensitivities=NAMES, method=method)
        assert np.array_equal(ens.sensitivity_trajectories[i], alone.sensitivities)
        assert np.array_equal(ens.sensitivities[i], alone.sensitivities[-1])
        assert np.array_equal(ens["theta"][i], alone["theta"])
        assert np.array_equal(ens.sensitivity("theta", "l")[i], alone.sensitivity("theta", "l"))
        m = ens.member(i)
        assert np.array_equal(m.sensitivities, alone.sensitivities)
        assert np.array_equal(m.sensitivity("energy", "g"), alone.sensitivity("energy", "g"))
        assert ens.stats["steps"][i] == alone.stats["steps"] > 0
    assert np.all(ens.status == 0) and ens.method == method
    # an independent fact: d theta(t) / d theta(0) = 1 at t = 0 and the energy's d E/d theta_dot(0)
    # = m l^2 theta_dot(0) = 0 for members started at rest, at every time (to the tolerance; E ~ 10)
    assert np.allclose(ens.sensitivity("theta", "theta(0)")[:, 0], 1.0)
    assert np.max(np.abs(ens.sensitivity("energy", "theta_dot(0)"))) < 1e-6


def test_final_only_and_errors(pend):
    t = np.linspace(0.0, 1.0, 11)
    ens = pend.ensemble(t, q0=np.array([[0.3], [0.5]]), sensitivities=["g"])
    assert ens.sensitivity_trajectories is None
    alone = pend.simulate(t, q0=[0.5], sensitivities=["g"])
    assert np.array_equal(ens.sensitivity("theta", "g")[1], alone.sensitivity("theta", "g")[-1])
    assert ens.member(1).sensitivities.shape == (1, 1, 3)
    with pytest.raises(LagcodegenError, match="'c' is neither a run-time parameter"):
        pend.ensemble(t, q0=np.array([[0.3], [0.5]]), sensitivities=["c"])
    with pytest.raises(LagcodegenError, match="no sensitivities"):
        pend.ensemble(t, q0=np.array([[0.3], [0.5]])).sensitivity("theta", "g")
    with pytest.raises(LagcodegenError, match="not a sensitivity direction"):
        ens.sensitivity("theta", "l")


def test_executor_chunks_carry_sensitivities(pend):
    from concurrent.futures import ThreadPoolExecutor
    t = np.linspace(0.0, 1.0, 11)
    q0 = np.array([[0.1], [0.2], [0.3], [0.4]])
    with ThreadPoolExecutor(2) as ex:
        ens = pend.ensemble(t, q0=q0, executor=ex, chunk_size=2, save="trajectory", sensitivities=["l"])
    ref = pend.ensemble(t, q0=q0, save="trajectory", sensitivities=["l"])
    assert np.array_equal(ens.sensitivity_trajectories, ref.sensitivity_trajectories)
    assert np.array_equal(ens.sensitivities, ref.sensitivities)


@pytest.mark.parametrize("threads", [1, 2])
def test_ctrl_c_keeps_the_members_that_finished(pend, monkeypatch, threads):
    """A KeyboardInterrupt while member 2 runs (as the driver raises it after Ctrl-C): an
    EnsembleInterrupted holding members 0 and 1 as they finished, member 2 and, on one thread, the
    rest never run (-82)."""
    from lagcodegen.solvers.cvode import sensitivity_ensemble
    from lagcodegen.solvers.ensemble_result import EnsembleInterrupted
    real = sensitivity_ensemble.solve_sensitivities

    def interrupted(cm, t, y0, *args, **kw):
        if y0[0] == 0.3:
            raise KeyboardInterrupt
        return real(cm, t, y0, *args, **kw)

    monkeypatch.setattr(sensitivity_ensemble, "solve_sensitivities", interrupted)
    t = np.linspace(0.0, 1.0, 11)
    with pytest.raises(EnsembleInterrupted) as info:
        pend.ensemble(t, q0=np.array([[0.1], [0.2], [0.3], [0.4]]), threads=threads, sensitivities=["l"])
    part = info.value.result
    assert list(part.status[:3]) == [0, 0, -82]
    alone = pend.simulate(t, q0=[0.2], sensitivities=["l"])
    assert np.array_equal(part.sensitivities[1], alone.sensitivities[-1])
    assert np.isnan(part.sensitivities[2]).all()
    if threads == 1:
        assert part.status[3] == -82
