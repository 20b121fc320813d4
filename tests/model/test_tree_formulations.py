"""What works for point-mass systems works for rigid-body trees (Model.link): constrained
formulations (index-1 on CVODE, GGL on IDA) with an end-effector constraint, events, Taylor,
Fortran and bundles, each checked against the same arm written out by hand as a closed form
(independent: its T and V typed from the geometry, no link in it), against conservation of h and
against the constraint itself."""

import csv
import subprocess

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen import ModelError, Scene, derive, write_bundle
from lagcodegen.api import compile_constrained
from lagcodegen.model.events import Event
from lagcodegen.theory.constraints import ConstrainedSystem

from helpers import G

# Two links hanging from the world, both hinged about x; centres of mass off the plane of motion
# (x offsets) and products of inertia, which a planar swing about x must not feel.
L1, L2 = 0.8, 0.6
M1, M2 = 1.3, 0.9
C1, C2 = (0.05, 0.0, -0.4), (-0.03, 0.0, -0.3)  # centres of mass in the link frames (on the link's axis)
I1, I2 = (0.07, 0.05, 0.02, 0.004, -0.003, 0.001), (0.03, 0.025, 0.01, -0.002, 0.001, 0.002)
TIP_Y = 0.9  # the constraint: the tip of the second link on the vertical plane y = TIP_Y
Q0 = (0.45, 1.1)  # (a, b) with the tip at y ~ 0.9 (set exactly by tip_state)


def arm_tree(name="arm", exact=False):
    """The arm as a tree of links (``exact``: its data as rationals, for symbolic checks)."""
    x = (lambda v: sp.nsimplify(v, rational=True)) if exact else (lambda v: v)
    m = lcg.Model(name)
    g, = m.parameters(g=G)
    m.gravity(g)
    m.link("l1", joint=lcg.Joint.revolute("a", (1, 0, 0)), mass=x(M1), com=tuple(map(x, C1)),
           inertia=tuple(map(x, I1)))
    m.link("l2", parent="l1", joint=lcg.Joint.revolute("b", (1, 0, 0)), origin=lcg.Placement((0, 0, -x(L1))),
           mass=x(M2), com=tuple(map(x, C2)), inertia=tuple(map(x, I2)))
    return m


def arm_closed(name="armc"):
    """The same arm as a closed form: angles a and a + b from the downward vertical in the y-z
    plane; T of each link = 1/2 m |v_G|^2 + 1/2 Ixx(G) w^2, V = g sum m z_G."""
    m = lcg.Model(name)
    a, b = m.coordinates("a b")
    g, = m.parameters(g=G)
    ad, bd = m.dot(a), m.dot(b)
    r1, r2 = -C1[2], -C2[2]
    y1, z1 = r1 * sp.sin(a), -r1 * sp.cos(a)
    y2, z2 = L1 * sp.sin(a) + r2 * sp.sin(a + b), -L1 * sp.cos(a) - r2 * sp.cos(a + b)
    v1 = (sp.diff(y1, a) * ad) ** 2 + (sp.diff(z1, a) * ad) ** 2
    v2 = (sp.diff(y2, a) * ad + sp.diff(y2, b) * bd) ** 2 + (sp.diff(z2, a) * ad + sp.diff(z2, b) * bd) ** 2
    m.kinetic_energy(M1 * v1 / 2 + I1[0] * ad ** 2 / 2 + M2 * v2 / 2 + I2[0] * (ad + bd) ** 2 / 2)
    m.potential_energy(g * (M1 * z1 + M2 * z2))
    return m


def tip_y(a, b):
    return L1 * sp.sin(a) + L2 * sp.sin(a + b)


def tip_state():
    """(q0, v0) on the constraint y_tip = TIP_Y: b solved for a = Q0[0]; a' = 0.7, b' from the
    constraint's derivative."""
    a0 = Q0[0]
    s = (TIP_Y - L1 * np.sin(a0)) / L2
    b0 = np.arcsin(s) - a0
    ad = 0.7
    bd = -ad * (L1 * np.cos(a0) + L2 * np.cos(a0 + b0)) / (L2 * np.cos(a0 + b0))
    return [a0, b0], [ad, bd]


def pinned(model, tree: bool):
    a, b = model.coords
    if tree:  # the end-effector point of the second link, from the tree's own kinematics
        y = model.point_on("l2", (0, 0, -L2), name="tip").position[1]
    else:
        y = tip_y(a, b)
    return ConstrainedSystem(model, holonomic=[y - TIP_Y])


T_OUT = np.linspace(0, 4, 81)


@pytest.fixture(scope="module")
def closed_run():
    sim = lcg.compile_model(arm_closed(), jacobian=False)
    return sim.simulate(T_OUT, q0=[0.9, -0.4], v0=[0.3, -1.2], rtol=1e-12, atol=1e-13)


def test_tree_and_closed_form_give_the_same_equations_and_trajectory(closed_run):
    tree, closed = derive(arm_tree()), derive(arm_closed())
    rng = np.random.default_rng(3)
    a, b = arm_tree().coords
    for _ in range(10):
        q, v = rng.uniform(-2, 2, 2), rng.uniform(-2, 2, 2)
        vals = {"a": q[0], "b": q[1], "a_dot": v[0], "b_dot": v[1], "g": G}
        subs = {s: vals[s.name] for s in tree.M.free_symbols | tree.F.free_symbols | closed.F.free_symbols}
        np.testing.assert_allclose(np.array(tree.M.subs(subs), dtype=float), np.array(closed.M.subs(subs), dtype=float),
                                   rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(np.array(tree.F.subs(subs), dtype=float), np.array(closed.F.subs(subs), dtype=float),
                                   rtol=1e-12, atol=1e-12)
    res = lcg.compile_model(arm_tree(), jacobian=True).simulate(T_OUT, q0=[0.9, -0.4], v0=[0.3, -1.2], rtol=1e-12,
                                                                   atol=1e-13)
    assert np.abs(res.y - closed_run.y).max() < 1e-8


def test_taylor_and_fortran_on_the_tree_follow_the_closed_form(closed_run):
    res = lcg.compile_model(arm_tree("armt"), jacobian=False).simulate(T_OUT, q0=[0.9, -0.4], v0=[0.3, -1.2],
                                                                       method="taylor", rtol=1e-13, atol=1e-13)
    assert np.abs(res.y - closed_run.y).max() < 1e-8
    res = lcg.compile_model(arm_tree("armf"), jacobian=True, lang="fortran").simulate(
        T_OUT, q0=[0.9, -0.4], v0=[0.3, -1.2], rtol=1e-12, atol=1e-13)
    assert np.abs(res.y - closed_run.y).max() < 1e-8


@pytest.mark.parametrize("formulation", ["index1", "ggl"])
def test_end_effector_pinned_to_a_plane(formulation):
    """Index-1 (CVODE) and GGL (IDA) on the tree with its tip held on the plane y = TIP_Y: the
    constraint holds, h is conserved (the constraint does no work) and the motion and the
    multiplier are the closed-form arm's under the same constraint."""
    q0, v0 = tip_state()
    out = ["energy", "lambda"]
    runs = {}
    for tree in (True, False):
        model = arm_tree(f"pin{formulation}") if tree else arm_closed(f"pinc{formulation}")
        sim = compile_constrained(pinned(model, tree), formulation, outputs=out)
        runs[tree] = sim.simulate(T_OUT, q0=q0, v0=v0, rtol=1e-11, atol=1e-12)
    res, ref = runs[True], runs[False]
    a, b = res.y[:, 0], res.y[:, 1]
    assert np.abs(L1 * np.sin(a) + L2 * np.sin(a + b) - TIP_Y).max() < 1e-8
    e = res["energy"]
    assert np.abs(e - e[0]).max() < 1e-7 * max(1.0, abs(e[0]))
    assert np.abs(res.y[:, :4] - ref.y[:, :4]).max() < 1e-7
    assert np.abs(res["lambda_0"] - ref["lambda_0"]).max() < 1e-6 * max(1.0, np.abs(ref["lambda_0"]).max())
    assert np.ptp(res.y[:, 0]) > 0.1  # it moved


def test_events_on_a_constrained_tree_match_the_closed_form():
    """A non-terminal event (a crosses 0.3 downwards) and a terminal one (b' crosses zero upwards)
    at the same times as on the closed-form arm."""
    q0, v0 = tip_state()
    times = {}
    for tree in (True, False):
        model = arm_tree("evt") if tree else arm_closed("evc")
        a, b = model.coords
        events = [Event("low", a - 0.3, direction=-1, terminal=False),
                  Event("turn", model.dot(b), direction=+1, terminal=True)]
        sim = compile_constrained(pinned(model, tree), "index1", events=events)
        res = sim.simulate(np.linspace(0, 6, 121), q0=q0, v0=v0, rtol=1e-11, atol=1e-12)
        times[tree] = [(e.name, e.t) for e in res.events]
        assert res.events and res.events[-1].name == "turn" and res.t[-1] == res.events[-1].t
    assert [n for n, _ in times[True]] == [n for n, _ in times[False]]
    assert np.allclose([t for _, t in times[True]], [t for _, t in times[False]], atol=1e-8)


def test_taylor_events_on_a_free_tree():
    """Taylor's own events on the unconstrained tree: the times a crosses 0 equal the closed form's."""
    found = {}
    for tree in (True, False):
        model = arm_tree("tev") if tree else arm_closed("tevc")
        a, _ = model.coords
        sim = lcg.compile_model(model, jacobian=False)
        res = sim.simulate([0, 4], q0=[0.9, -0.4], v0=[0.3, -1.2], method="taylor", rtol=1e-13, atol=1e-13,
                           events=[Event("zero", a, direction=0, terminal=False)])
        found[tree] = [e.t for e in res.events]
    assert len(found[True]) >= 2 and len(found[True]) == len(found[False])
    assert np.allclose(found[True], found[False], atol=1e-9)


def test_expanded_jacobian_of_a_tree_is_refused_with_the_way_out():
    scene = Scene(derive(arm_tree("exp")), jacobian=True, jacobian_form="expanded")
    with pytest.raises(ModelError, match="expanded Jacobian of a rigid-body tree.*tangent"):
        lcg.generate_code(scene)


@pytest.mark.parametrize("lang", ["c", "fortran"])
def test_bundle_of_a_tree_builds_strictly_and_matches_cvode(tmp_path, tools, lang):
    """The bundle's RK4 example (make check) on the tree, its C compiled with -Wall -Wextra -Werror
    -std=c99 -pedantic, ends where lagcodegen's own CVODE run does."""
    scene = Scene(derive(arm_tree("armb")), outputs=["energy"], jacobian=False)
    y0 = [0.9, -0.4, 0.3, -1.2]
    write_bundle(scene, tmp_path, lang=lang, y0=y0, t_end=2.0)
    flags = "-O1 -Wall -Wextra -Werror -std=c99 -pedantic"
    proc = subprocess.run(["make", f"CFLAGS={flags}", "check"], cwd=tmp_path, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = list(csv.reader((tmp_path / "rk4_example.csv").read_text().splitlines()))
    final = np.array([float(v) for v in rows[-1]])
    ref = lcg.build_code(lcg.generate_code(scene)).simulate([0, 2.0], y0=y0, rtol=1e-11, atol=1e-12)
    assert final[0] == 2.0
    np.testing.assert_allclose(final[1:5], ref.y[-1], rtol=0, atol=1e-6)


@pytest.mark.parametrize("n,jacobian", [(2, True), (12, False)])
def test_tree_sources_compile_strictly(tmp_path, n, jacobian):
    """Every C file of a tree model (the program form, the tangent Jacobian, the inverse dynamics;
    at 12 links the pieces cut into parts) compiles with -Wall -Wextra -Werror -std=c99 -pedantic."""
    from helpers import STRICT_CFLAGS
    if n == 2:
        model = arm_tree("strict")
    else:
        model = lcg.Model("strict12")
        model.gravity(G)
        parent = None
        for i in range(n):
            parent = model.link(f"l{i}", parent=parent, joint=lcg.Joint.revolute(f"j{i}", [(1, 0, 0), (0, 1, 0),
                                                                                          (0.6, 0, 0.8)][i % 3]),
                                origin=lcg.Placement((0.1, 0.05 * i, -0.3), rpy=(0.1 * i, -0.2, 0.3)), mass=1.0 + 0.1 * i,
                                com=(0.02, -0.01, -0.15), inertia=(0.02, 0.03, 0.01, 0.001, -0.002, 0.0015)).name
    code = lcg.generate_code(Scene(derive(model), jacobian=jacobian))
    assert any(name.endswith("_dynamics.c") for name in code.files)
    for name, text in code.files.items():
        (tmp_path / name).write_text(text)
    for name in code.files:
        if not name.endswith(".c"):
            continue
        parts = code.split.get(name, 1)
        for flags in ([[]] if parts == 1 else [[f"-DLCG_PARTS={parts}", f"-DLCG_PART={k}"] for k in range(parts)]):
            proc = subprocess.run(["cc", *STRICT_CFLAGS, "-O0", *flags, "-c", name, "-o", "x.o"], cwd=tmp_path,
                                  capture_output=True, text=True, timeout=600)
            assert proc.returncode == 0, proc.stderr[-3000:]
    if n == 12:
        assert code.split, "a 12-link tree's program is cut into parts"


# ---------------------------------------------------------------------- theory on trees
def test_minimal_coordinates_of_a_constrained_tree_follow_index1():
    """Formulation "minimal" on the tree with its joints geared (b = -2 a) solves the constraint
    for one angle and turns the links into rigid bodies at their world poses: the same motion
    as index-1 on the tree, and h conserved."""
    def geared(name):
        m = arm_tree(name)
        a, b = m.coords
        return ConstrainedSystem(m, holonomic=[b + 2 * a])
    q0, v0 = [0.3, -0.6], [0.5, -1.0]
    ref = compile_constrained(geared("gear1"), "index1").simulate(T_OUT, q0=q0, v0=v0, rtol=1e-11, atol=1e-12)
    res = compile_constrained(geared("gear"), "minimal", outputs=["energy"]).simulate(T_OUT, q0=q0, v0=v0,
                                                                                     rtol=1e-11, atol=1e-12)
    for k, name in enumerate(("a", "b")):
        assert np.abs(res[name] - ref.y[:, k]).max() < 1e-7
        assert np.abs(res[f"{name}_dot"] - ref.y[:, 2 + k]).max() < 1e-6
    assert np.ptp(res["a"]) > 0.2
    e = res["energy"]
    assert np.abs(e - e[0]).max() < 1e-8 * max(1.0, abs(e[0]))


def test_energy_theory_counts_the_links():
    from lagcodegen.theory.energy import check_jacobi, is_natural, kinetic_split
    model = arm_tree("theory", exact=True)
    eom = derive(model)
    assert is_natural(model)
    split = kinetic_split(eom)
    assert split.natural
    vals = {s: 0.3 + 0.1 * k for k, s in enumerate(sorted(split.alpha.free_symbols | eom.M.free_symbols,
                                                           key=lambda s: s.name))}
    assert sp.simplify(split.T2 - eom.T) == 0
    np.testing.assert_allclose(np.array(split.alpha.subs(vals), dtype=float), np.array(eom.M.subs(vals), dtype=float),
                               rtol=1e-12, atol=1e-14)
    check = check_jacobi(eom)
    assert check.holds and check.conserved and check.equals_T_plus_V and check.lagrangian
    moving = arm_tree("moving")
    moving.links[1].origin = lcg.Placement((0, 0, -L1 + 0.1 * sp.sin(moving.t)))
    assert not is_natural(moving)


def test_jacobi_h_of_a_ur_like_arm_is_conserved_over_ten_seconds():
    """Free motion of the six-joint arm from examples/ur_like_arm.urdf (its joint damping set to
    zero): h stays within the integrator's tolerance, on CVODE and on Taylor."""
    import re
    from pathlib import Path

    from lagcodegen import urdf
    text = (Path(__file__).resolve().parents[2] / "examples" / "ur_like_arm.urdf").read_text()
    text = re.sub(r'damping="[^"]*"', 'damping="0"', text)
    model = urdf.loads(text, filename="ur_like_arm.urdf")
    sim = lcg.compile_model(model, jacobian=False, outputs=["jacobi_h"])
    n = model.n
    q0, v0 = np.linspace(-0.8, 0.9, n), np.linspace(1.0, -0.5, n)
    for method, tol in (("cvode", 1e-11), ("taylor", 1e-12)):
        opts = {} if method == "cvode" else {"method": "taylor"}
        res = sim.simulate(np.linspace(0, 10, 201), q0=q0, v0=v0, rtol=tol, atol=tol, **opts)
        h = res["jacobi_h"]
        assert np.ptp(res.y[:, 0]) > 0.5  # it moved
        assert np.abs(h - h[0]).max() <= 1e-7 * max(1.0, abs(h[0])), method
