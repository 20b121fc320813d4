"""examples/identify_arm.py: the Panda's base inertial parameters (and joint damping) identified
by least squares on the inverse-dynamics regressor from noisy computed torques: every estimate
within 3 of its standard errors of the truth, the number of base parameters the rank of
Pinocchio's stacked joint-torque regressor at the same states."""

import importlib.util
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "identify_arm.py"


@pytest.fixture(scope="module")
def example():
    spec = importlib.util.spec_from_file_location("identify_arm", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def found(example):
    return example.run(quick=True, seed=0)


def test_every_base_parameter_within_3_standard_errors(found, example):
    assert found["samples"] == 400 and found["columns"] == 77
    assert np.all(np.abs(found["z"]) < 3), found["z"]
    assert found["sigma_hat"] == pytest.approx(example.SIGMA, rel=0.05)


def test_base_parameter_count_is_the_rank_of_pinocchios_regressor(found, example):
    """r = 50 (43 inertial base parameters, as Gaz et al. 2019 for the Panda, + 7 dampings):
    the rank of Pinocchio's regressor stacked with diag(q') over the same states."""
    path = example.panda_urdf()
    full = pin.buildModelFromUrdf(str(path))
    pm = pin.buildReducedModel(full, [full.getJointId(n) for n in example.FINGERS], pin.neutral(full))
    data = pm.createData()
    rows = [np.hstack([pin.computeJointTorqueRegressor(pm, data, q, v, a), np.diag(v)])
            for q, v, a in zip(found["q"][::4], found["v"][::4], found["a"][::4])]
    W = np.vstack(rows)
    s = np.linalg.svd(W, compute_uv=False)
    assert found["rank"] == int(np.sum(s > 1e-8 * s[0])) == 50


def test_regressor_reproduces_the_torques(found):
    """The stacked regressor times the true pi is the computed torques (the truth the
    identification is judged by is consistent with the data)."""
    W, perm, r = found["W"], found["perm"], found["rank"]
    tau = found["tau"].ravel()
    fit = W[:, perm[:r]] @ found["beta_true"]
    assert np.abs(fit - tau).max() < 1e-9 * np.abs(tau).max()
