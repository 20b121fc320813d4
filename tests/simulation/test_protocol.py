"""The faces of lagcodegen.simulation behind one protocol: the same names, the same run keywords
(with the face's own: y0/z0 for a scene's state, initial/ic_tol for a constrained one; contacts=
for one with contacts goes through **options, not a name of the signature), pickling."""

import inspect
import pickle

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen.simulation import Simulation
from lagcodegen.simulation.constrained import ConstrainedSimulation
from lagcodegen.simulation.minimal import MinimalSimulation
from lagcodegen.simulation.ode import CompiledModel

FACES = (CompiledModel, ConstrainedSimulation, MinimalSimulation)
SHARED = ["t", "q0", "v0", "params", "solver", "rtol", "atol", "events", "raise_on_error", "options"]
OWN = {CompiledModel: ["y0", "z0"], ConstrainedSimulation: ["initial", "ic_tol"],
       MinimalSimulation: ["initial", "ic_tol"]}


@pytest.mark.parametrize("face", FACES, ids=lambda c: c.__name__)
def test_every_face_takes_the_same_run_keywords(face):
    names = list(inspect.signature(face.simulate).parameters)[1:]
    assert sorted(names) == sorted(SHARED + OWN[face])
    assert names[:3] == ["t", "q0", "v0"]  # the positions callers use
    params = inspect.signature(face.simulate).parameters
    assert all(params[k].kind is inspect.Parameter.KEYWORD_ONLY for k in SHARED[3:-1])
    assert params["options"].kind is inspect.Parameter.VAR_KEYWORD
    ens = list(inspect.signature(face.ensemble).parameters)[1:]
    assert ens[:3] == ["t", "q0", "v0"] and "options" in ens and "solver" not in ens  # solver= goes in options
    for member in ("state_names", "param_names", "simulate", "ensemble", "__reduce__"):
        assert hasattr(face, member)


def test_a_compiled_scene_is_a_simulation_and_pickles_to_one():
    cm = lcg.compile_model(lcg.systems.pendulum(), outputs=["energy"])
    assert isinstance(cm, Simulation)
    again = pickle.loads(pickle.dumps(cm))
    assert isinstance(again, Simulation)
    t = np.linspace(0, 1, 11)
    assert np.array_equal(again.simulate(t, [0.4]).y, cm.simulate(t, q0=[0.4]).y)
