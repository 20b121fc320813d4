"""The one entry of a solver family (issue 36): ``family.run(face, Problem, Request)``, with what
each family takes declared once in its ``runs`` table and every other combination refused by
name before anything runs; sensitivities asked as one ``Sensitivities`` value."""

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen.errors import LagcodegenError
from lagcodegen.solvers import registry
from lagcodegen.solvers.family import FACES, RUN_KINDS, Members, Problem, Request, Sensitivities


@pytest.fixture(scope="module")
def pend():
    return lcg.compile_model(lcg.systems.pendulum(), outputs=["energy"])


def test_every_family_declares_its_runs_once():
    for cls in registry.FAMILIES.values():
        assert cls.runs, cls.name
        for (face, how), (function, allowed) in cls.runs.items():
            assert face in cls.faces and face in FACES and how in RUN_KINDS, (cls.name, face, how)
            assert callable(function) and frozenset() in allowed, (cls.name, face, how)
            assert all(a <= {"events", "inputs", "sensitivities", "impacts"} for a in allowed)
        # every face a family integrates has at least a run to output times
        assert all((face, "run") in cls.runs for face in cls.faces), cls.name


def test_the_entry_runs_what_simulate_runs_bit_for_bit(pend):
    t = np.linspace(0, 3, 31)
    y = np.array([0.7, 0.0])
    p = pend.parameter_vector()
    for family in (lcg.CVODE(method="bdf"), lcg.Taylor()):
        res = family.run("ode", Problem(pend, 1e-9, 1e-11, t, y, p))
        ref = pend.simulate(t, y0=y, solver=family, rtol=1e-9, atol=1e-11)
        assert np.array_equal(res.y, ref.y), family.name
    # an ensemble of two members through the same entry, member 0 the run above
    Y = np.array([y, [0.2, 0.1]])
    ens = lcg.CVODE().run("ode", Problem(pend, 1e-9, 1e-11, t, Y, p), Request(members=Members(save="trajectory")))
    one = pend.simulate(t, y0=Y[1], rtol=1e-9, atol=1e-11, method="adams")
    assert np.array_equal(ens.member(1).y, one.y)


def test_combinations_a_family_does_not_take_are_refused_by_name(pend):
    t = np.linspace(0, 1, 5)
    event = lcg.Event("down", "theta")
    with pytest.raises(LagcodegenError, match="Taylor ensembles do not take them without sensitivities"):
        lcg.Taylor().check("ode", Request(events=(), inputs=object(), members=Members()))
    assert lcg.Taylor().supports("ode", Request(events=(event,), members=Members()))  # ensembles with events
    with pytest.raises(LagcodegenError, match="events with input tables"):
        lcg.CVODE().check("ode", Request(events=(event,), inputs=object()))
    with pytest.raises(LagcodegenError, match="IDA has no run runner for the ODE"):
        lcg.IDA().run("ode", Problem(pend, 1e-8, 1e-10, t, np.zeros(2), pend.parameter_vector()))
    # nothing ran: the refusal comes from the table, and says what the family takes
    refused = r"prepared run of the ODE .* with events and sensitivities together is not supported \(it takes: plain; "
    with pytest.raises(LagcodegenError, match=refused + r"sensitivities\)"):
        lcg.CVODE(sensitivities=["g"]).check("ode", Request(kind="prepared", events=(event,)))
    assert lcg.CVODE().supports("ode", Request(kind="prepared"))
    assert not lcg.CVODE().supports("ode", Request(kind="prepared", events=(event,)))
    assert lcg.Taylor().supports("ode", Request(kind="prepared", events=(event,)))


def test_sensitivities_as_one_value(pend):
    t = np.linspace(0, 2, 21)
    for method in ("bdf", "taylor"):
        a = pend.simulate(t, q0=[0.5], method=method, sensitivities=Sensitivities(["g", "theta(0)"], errcon=False))
        b = pend.simulate(t, q0=[0.5], method=method, sensitivities=["g", "theta(0)"], sensitivity_errcon=False)
        c = pend.simulate(t, q0=[0.5], method=method, sensitivities=["g", "theta(0)"])
        assert np.array_equal(a.sensitivity("theta", "g"), b.sensitivity("theta", "g")), method
        assert not np.array_equal(a.sensitivity("theta", "g"), c.sensitivity("theta", "g")), method
    family = lcg.CVODE(sensitivities=Sensitivities("g", corrector="simultaneous"))
    assert family.sensitivities == ("g",) and family.sensitivity_corrector == "simultaneous"
    assert Sensitivities.of(family) == Sensitivities(("g",), True, "simultaneous")
    with pytest.raises(LagcodegenError, match="Taylor has no corrector choice"):
        lcg.Taylor(sensitivities=Sensitivities(["g"], corrector="simultaneous"))
    with pytest.raises(LagcodegenError, match="corrector must be one of"):
        Sensitivities(["g"], corrector="fast")


def test_contacts_are_asked_through_the_entry_and_refused_by_the_table():
    """A system with contacts: simulate asks the family for a run with impacts; CVODE runs it,
    the table refuses sensitivities with impacts; IDA runs integrator objects with impacts."""
    import sympy as sp
    m = lcg.Model("entry_ball")
    (y,) = m.coordinates("y")
    m.parameters(g=9.81, m=1.0)
    m.particle("b", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    system = lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=0.5)])
    sim = lcg.compile_constrained(system, "index1")
    assert lcg.CVODE().supports("index1", Request(contacts=object()))
    assert not lcg.CVODE(sensitivities=["g"]).supports("index1", Request(contacts=object()))
    assert lcg.IDA().supports("ggl", Request(kind="stepper", contacts=object()))
    res = sim.simulate(np.linspace(0, 1, 11), q0=[1.0], v0=[0.0], rtol=1e-10, atol=1e-12)
    t1 = np.sqrt(2 / 9.81)
    assert abs(res.impacts.times[0] - t1) < 1e-9
    with pytest.raises(LagcodegenError, match="sensitivities of systems with contacts"):
        sim.simulate([0, 1], q0=[1.0], v0=[0.0], sensitivities=["g"])
