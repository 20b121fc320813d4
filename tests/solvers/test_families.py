"""Solver families as objects (lagcodegen.solvers.family, .registry): each options object checks
its values once, when made; the keyword spellings of simulate() and solver= objects resolve
through one code path into the same object, so that both run the same numbers; a keyword a
family does not have is refused by name; a family is one registry entry."""

from dataclasses import dataclass

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen import LagcodegenError, ModelError
from lagcodegen.result import Result
from lagcodegen.solvers import registry
from lagcodegen.solvers.family import FACES, Family, combinations
from lagcodegen.solvers.registry import CVODE, IDA, Taylor, resolve

from helpers import cartesian_pendulum, pendulum_q0


# ---------------------------------------------------------------------- the objects
@pytest.mark.parametrize("make, words", [
    (lambda: CVODE(method="rk4"), "method must be one of adams, bdf, got 'rk4'"),
    (lambda: CVODE(linear_solver="banded"), "linear_solver must be one of dense, band, fixedpoint"),
    (lambda: CVODE(linear_solver="band", backend="sksundae"), "needs backend='native'"),
    (lambda: CVODE(projection=True, method="adams"), "needs method='bdf'"),
    (lambda: CVODE(max_steps=0), "max_steps must be a positive integer"),
    (lambda: CVODE(max_wall=-1.0), "max_wall must be a finite number >= 0"),
    (lambda: IDA(backend="scipy"), "backend must be one of native, sksundae"),
    (lambda: IDA(alg_atol=float("nan")), "alg_atol"),
    (lambda: Taylor(order=1), "order must be an integer >= 2"),
])
def test_options_objects_check_their_values_when_made(make, words):
    with pytest.raises(LagcodegenError, match=words.replace("(", r"\(").replace(")", r"\)")):
        make()


def test_baumgarte_is_checked_and_normalized_once():
    assert CVODE(baumgarte=(5, 2)).baumgarte == (5.0, 2.0)
    assert CVODE(baumgarte="auto").baumgarte == "auto"
    with pytest.raises(ModelError, match="baumgarte must be 'auto' or"):
        CVODE(baumgarte="fast")


def test_options_objects_are_frozen_keyword_only_and_hashable():
    opts = CVODE(method="bdf")
    with pytest.raises(AttributeError):
        opts.method = "adams"
    with pytest.raises(TypeError):
        CVODE("bdf")  # keyword-only
    assert hash(opts) == hash(CVODE(method="bdf")) and opts == CVODE(method="bdf")


# ---------------------------------------------------------------------- the registry
def test_every_face_has_a_default_family_and_every_family_runs_a_face():
    for face in ("ode", "index1", "ggl"):
        assert type(resolve(face, None, {})) in registry.FAMILIES.values()
    assert resolve("ode", None, {}) == CVODE()
    assert resolve("index1", None, {}) == CVODE()
    assert resolve("ggl", None, {}) == IDA()
    for cls in registry.FAMILIES.values():
        assert cls.faces and set(cls.faces) <= set(FACES)
        for face in cls.faces:  # every face a family claims has its runner and its ensemble runner
            assert callable(getattr(cls, f"run_{face}")) and callable(getattr(cls, f"ensemble_{face}"))


def test_keyword_spellings_become_the_family_object():
    assert resolve("ode", None, {"method": "bdf", "linear_solver": "band"}) == CVODE(method="bdf",
                                                                                      linear_solver="band")
    assert resolve("ode", None, {"method": "taylor", "order": 8}) == Taylor(order=8)
    assert resolve("ggl", None, {"method": "bdf", "suppress_alg": False}) == IDA(suppress_alg=False)
    assert resolve("index1", None, {"baumgarte": (5, 5), "projection": False}) == CVODE(baumgarte=(5.0, 5.0),
                                                                                        projection=False)
    # method="auto": Taylor for small models, Adams for large ones (choose_method)
    assert resolve("ode", None, {"method": "auto"}, n=2, rtol=1e-8) == Taylor()
    assert resolve("ode", None, {"method": "auto"}, n=50, rtol=1e-8) == CVODE(method="adams")


def test_unknown_and_inapplicable_keywords_are_refused_by_name():
    with pytest.raises(LagcodegenError, match="'linear_solvr' is not an option of CVODE"):
        resolve("ode", None, {"linear_solvr": "band"})
    with pytest.raises(LagcodegenError, match="'linear_solver' is not an option of Taylor"):
        resolve("ode", None, {"method": "taylor", "linear_solver": "band"})
    with pytest.raises(LagcodegenError, match="'order', 'bandwidths' are not an option of IDA"):
        resolve("ggl", None, {"order": 5, "bandwidths": (1, 1)})
    with pytest.raises(LagcodegenError, match="'linear_solver': option of CVODE that a constrained system in "
                                              "the index-1 form does not take"):
        resolve("index1", None, {"linear_solver": "band"})
    with pytest.raises(LagcodegenError, match="'baumgarte': option of CVODE that the ODE of a compiled scene"):
        resolve("ode", None, {"baumgarte": (1, 1)})
    with pytest.raises(LagcodegenError, match="IDA integrates a constrained system in the GGL form, not the ODE"):
        resolve("ode", IDA(), {})
    with pytest.raises(LagcodegenError, match="IDA integrates with BDF only"):
        resolve("ggl", None, {"method": "adams"})
    with pytest.raises(LagcodegenError, match="method must be one of adams, bdf, taylor, auto, got 'rk45'"):
        resolve("ode", None, {"method": "rk45"})
    with pytest.raises(LagcodegenError, match="solver must be CVODE"):
        resolve("ode", "cvode", {})


def test_keywords_that_ask_for_nothing_are_accepted_everywhere():
    """backend="native", linear_solver="dense" (what the command line passes for every method)
    ask for nothing a family lacks; Taylor takes no Jacobian, so jacobian= has no effect there."""
    assert resolve("ode", None, {"method": "taylor", "backend": "native", "linear_solver": "dense",
                                 "jacobian": True}) == Taylor()
    assert resolve("ggl", None, {"method": "bdf", "linear_solver": "dense", "baumgarte": None,
                                 "projection": False}) == IDA()
    with pytest.raises(LagcodegenError, match="'projection' is not an option of IDA"):
        resolve("ggl", None, {"projection": True})


def test_keywords_beside_an_object_complete_it_but_never_contradict_it():
    assert resolve("ode", CVODE(method="bdf"), {"max_steps": 10}) == CVODE(method="bdf", max_steps=10)
    assert resolve("ode", CVODE(method="bdf"), {"method": "bdf"}) == CVODE(method="bdf")
    with pytest.raises(LagcodegenError, match="method='adams' contradicts solver=CVODE"):
        resolve("ode", CVODE(method="bdf"), {"method": "adams"})
    with pytest.raises(LagcodegenError, match="method='adams' contradicts solver=Taylor"):
        resolve("ode", Taylor(), {"method": "adams"})
    with pytest.raises(LagcodegenError, match="order=6 contradicts"):
        resolve("ode", Taylor(order=8), {"order": 6})


# ---------------------------------------------------------------------- on compiled models
@pytest.fixture(scope="module")
def pend():
    return lcg.compile_model(lcg.systems.pendulum(), outputs=["energy"])


def test_an_object_and_its_keyword_spelling_run_the_same_numbers(pend):
    t = np.linspace(0, 5, 51)
    for obj, words in ((CVODE(method="bdf", max_order=3), dict(method="bdf", max_order=3)),
                       (Taylor(order=12), dict(method="taylor", order=12))):
        a = pend.simulate(t, q0=[1.0], solver=obj)
        b = pend.simulate(t, q0=[1.0], **words)
        assert np.array_equal(a.y, b.y) and a.stats["steps"] == b.stats["steps"] and a.method == b.method
        ens = pend.ensemble(t, q0=[[1.0], [0.5]], solver=obj, save="trajectory")
        assert np.array_equal(ens.member(0).y, a.y)  # simulate and ensemble resolve alike


def test_cached_resolutions_do_not_leak_between_runs_with_other_options(pend, monkeypatch):
    """The resolutions kept between calls (per keyword set) and the per-module option structs give
    every run what a fresh model and an empty cache give it, whichever run came before."""
    t = np.linspace(0, 4, 9)
    runs = [dict(method="taylor", rtol=1e-10), dict(method="adams", rtol=1e-6), dict(method="taylor", rtol=1e-5),
            dict(method="taylor", rtol=1e-5, max_steps=3), dict(method="bdf", rtol=1e-8, max_steps=5),
            dict(method="bdf", rtol=1e-8), dict(method="taylor", rtol=1e-10, order=6),
            dict(method="taylor", rtol=1e-10), dict(method="adams", rtol=1e-6, atol=1e-3)]
    again = [pend.simulate(t, q0=[1.0], raise_on_error=False, **kw) for kw in runs + runs[::-1]]
    for kw, res in zip(runs + runs[::-1], again):
        monkeypatch.setattr(registry, "_CACHE", {})
        fresh = lcg.compile_model(lcg.systems.pendulum(), outputs=["energy"])  # its own solver state
        ref = fresh.simulate(t, q0=[1.0], raise_on_error=False, **kw)
        assert res.status == ref.status and res.method == ref.method, kw
        assert res.t.shape == ref.t.shape and np.array_equal(res.y, ref.y), kw
        assert res.stats["steps"] == ref.stats["steps"], kw
    budgets = [r.status for r in again[3:5]]
    assert min(budgets) < 0 and again[2].status == 0  # the step budgets did take effect
    # values equal across types are not one key: order=2.0 is refused after order=2 ran
    pend.simulate(t, q0=[1.0], method="taylor", order=2, raise_on_error=False)
    with pytest.raises(LagcodegenError, match="order must be an integer"):
        pend.simulate(t, q0=[1.0], method="taylor", order=2.0)


def test_runs_refuse_what_their_family_cannot_do_before_running(pend):
    with pytest.raises(LagcodegenError, match="'linear_solver' is not an option of Taylor"):
        pend.simulate([0, 1], q0=[1.0], method="taylor", linear_solver="band")
    with pytest.raises(LagcodegenError, match="'threads' is not an option of CVODE"):
        pend.simulate([0, 1], q0=[1.0], threads=2)
    with pytest.raises(LagcodegenError, match="'projection' is not an option of Taylor"):
        pend.ensemble([0, 1], q0=[[1.0]], method="taylor", projection=True)
    with pytest.raises(LagcodegenError, match="'order' is not an option of CVODE"):
        pend.simulate([0, 1], q0=[1.0], order=4, events=[lcg.Event("down", "theta")])


@pytest.mark.parametrize("method", ["adams", "taylor"])
def test_max_wall_stops_a_single_run(pend, method):
    """A wall-clock budget on one run (new with the family objects; ensembles had it per member):
    the run stops with flag -81 after about max_wall seconds, partway."""
    res = pend.simulate((0.0, 1e7), q0=[1.0], method=method, rtol=1e-12, atol=1e-12, max_steps=10**9,
                        max_wall=0.05, raise_on_error=False)
    assert res.status == -81 and 0 < res.stats["t_reached"] < 1e7 and res.t[-1] <= res.stats["t_reached"]


@dataclass(frozen=True, kw_only=True)
class Euler(Family):
    """A toy family: explicit Euler with ``steps`` steps per output interval (through cm.rhs)."""

    name = "Euler"
    methods = ("euler",)
    faces = ("ode",)
    steps: int = 100

    def run_ode(self, problem, request):
        cm, t, y, p = problem.sim, problem.t, problem.y, problem.p
        rows = [y.copy()]
        for a, b in zip(t[:-1], t[1:]):
            h = (b - a) / self.steps
            for k in range(self.steps):
                y = y + h * cm.rhs(a + k * h, y, p)
            rows.append(y.copy())
        return Result(t=t.copy(), y=np.array(rows), state_names=list(cm.state_names), outputs={}, stats={},
                      status=0, message="success", backend="python", method="euler")

    #: Its one run: the ODE face, to output times, nothing asked beside (Family.run refuses the rest).
    runs = {("ode", "run"): (run_ode, combinations(""))}


def test_a_new_family_is_one_registry_line(pend, monkeypatch):
    """Registering a family (an options object with its runner) is all simulate needs: the
    keyword spelling and the object reach it, its own options are checked, others refused."""
    monkeypatch.setitem(registry.FAMILIES, "euler", Euler)
    monkeypatch.setattr(registry, "_CACHE", {})
    t = np.linspace(0, 0.5, 6)
    res = pend.simulate(t, q0=[0.3], method="euler", steps=2000)
    ref = pend.simulate(t, q0=[0.3], rtol=1e-12, atol=1e-12)
    assert res.method == "euler" and np.max(np.abs(res.y - ref.y)) < 1e-3  # first order, h = 5e-5
    assert np.array_equal(pend.simulate(t, q0=[0.3], solver=Euler(steps=2000)).y, res.y)
    with pytest.raises(LagcodegenError, match="'order' is not an option of Euler"):
        pend.simulate(t, q0=[0.3], method="euler", order=4)
    with pytest.raises(LagcodegenError, match="Euler has no ensemble runner"):
        pend.ensemble(t, q0=[[0.3]], method="euler")


# ---------------------------------------------------------------------- constrained faces
@pytest.fixture(scope="module")
def cp_minimal():
    return lcg.compile_constrained(cartesian_pendulum("fam_min"), "minimal")


def test_minimal_coordinates_refuse_what_they_cannot_do(cp_minimal):
    """Events that are no switch, Baumgarte stabilization and projection used to be dropped without a word."""
    q0 = pendulum_q0()
    with pytest.raises(LagcodegenError, match="events= of a run is True or False"):
        cp_minimal.simulate([0, 1], q0=q0, events=[lcg.Event("e", "x")])
    with pytest.raises(LagcodegenError, match="'baumgarte': option of CVODE that the ODE of a compiled scene"):
        cp_minimal.simulate([0, 1], q0=q0, baumgarte=(1.0, 1.0))
    with pytest.raises(LagcodegenError, match="'suppress_alg' is not an option of CVODE"):
        cp_minimal.ensemble([0, 1], q0=[q0], suppress_alg=False)
    res = cp_minimal.simulate([0, 1], q0=q0, events=False, method="bdf")
    assert res.success and res.method == "bdf"


def test_compile_constrained_refuses_options_of_other_formulations():
    system = cartesian_pendulum("fam_opts")
    with pytest.raises(ModelError, match="baumgarte=\\(1.0, 1.0\\) does not apply to formulation 'ggl'"):
        lcg.compile_constrained(system, "ggl", baumgarte=(1.0, 1.0))
    with pytest.raises(ModelError, match="unknown option 'elimnate'"):
        lcg.compile_constrained(system, "minimal", elimnate=["x"])
