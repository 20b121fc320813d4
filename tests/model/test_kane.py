"""Kane's method in: a sympy ``KanesMethod`` (after ``kanes_equations``) and a ``System`` whose speeds
are not q' (dependent speeds and velocity constraints included) through lagcodegen.derive and
compile_model, checked against sympy's own ``KanesMethod.rhs()`` (lambdified at the same state)
and against scipy integrating it."""

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from scipy.integrate import solve_ivp

import lagcodegen as lcg
from lagcodegen.errors import ModelError
from lagcodegen.model import mechanics

t = me.dynamicsymbols._t
VALUES = {"r": 0.5, "m": 2.0, "g": 9.81}


def rolling_disc(form=True):
    """sympy's rolling disc (sympy/physics/mechanics/tests/test_kane.py, the documentation's
    example): yaw, lean and spin q1, q2, q3, the body-frame angular speeds u1, u2, u3 in the lean
    frame, rolling without slip through the contact point's zero velocity. Returns (km, C)."""
    q1, q2, q3, u1, u2, u3 = me.dynamicsymbols("q1 q2 q3 u1 u2 u3")
    r, m, g = sp.symbols("r m g")
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [q1, N.z])
    L = Y.orientnew("L", "Axis", [q2, Y.x])
    R = L.orientnew("R", "Axis", [q3, L.y])
    w_R_N_qd = R.ang_vel_in(N)
    R.set_ang_vel(N, u1 * L.x + u2 * L.y + u3 * L.z)
    C = me.Point("C")
    C.set_vel(N, 0)
    Dmc = C.locatenew("Dmc", r * L.z)
    Dmc.v2pt_theory(C, N, R)
    inertia = me.inertia(L, m / 4 * r**2, m / 2 * r**2, m / 4 * r**2)
    kd = [me.dot(R.ang_vel_in(N) - w_R_N_qd, uv) for uv in L]
    disc = me.RigidBody("disc", Dmc, R, m, (inertia, Dmc))
    km = me.KanesMethod(N, q_ind=[q1, q2, q3], u_ind=[u1, u2, u3], kd_eqs=kd)
    if form:
        km.kanes_equations([disc], [(Dmc, -m * g * Y.z)])
    return km, C


def disc_with_dependent_speeds(as_system=False):
    """The rolling disc with the contact point's position q4, q5 in the ground plane and its
    velocity components u4, u5 (along the yaw frame) as dependent speeds, fixed by the
    nonholonomic constraints that the disc's material point in contact has no horizontal
    velocity. Returns (km or System, fixed point O, velocity constraints)."""
    q1, q2, q3, q4, q5 = me.dynamicsymbols("q1 q2 q3 q4 q5")
    u1, u2, u3, u4, u5 = me.dynamicsymbols("u1 u2 u3 u4 u5")
    r, m, g = sp.symbols("r m g")
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [q1, N.z])
    L = Y.orientnew("L", "Axis", [q2, Y.x])
    R = L.orientnew("R", "Axis", [q3, L.y])
    w_R_N_qd = R.ang_vel_in(N)
    R.set_ang_vel(N, u1 * L.x + u2 * L.y + u3 * L.z)
    O = me.Point("O")
    O.set_vel(N, 0)
    C = O.locatenew("C", q4 * N.x + q5 * N.y)
    C.set_vel(N, u4 * Y.x + u5 * Y.y)
    Dmc = C.locatenew("Dmc", r * L.z)
    Dmc.set_vel(N, C.vel(N) + (r * L.z).dt(N))
    P = Dmc.locatenew("P", -r * L.z)
    P.v2pt_theory(Dmc, N, R)
    inertia = me.inertia(L, m / 4 * r**2, m / 2 * r**2, m / 4 * r**2)
    kd = [me.dot(R.ang_vel_in(N) - w_R_N_qd, uv) for uv in L]
    kd += [q4.diff(t) - (u4 * sp.cos(q1) - u5 * sp.sin(q1)), q5.diff(t) - (u4 * sp.sin(q1) + u5 * sp.cos(q1))]
    vc = [me.dot(P.vel(N), Y.x), me.dot(P.vel(N), Y.y)]
    disc = me.RigidBody("disc", Dmc, R, m, (inertia, Dmc))
    gravity = (Dmc, -m * g * Y.z)
    if as_system:
        system = me.System(N, O)
        system.add_coordinates(q1, q2, q3, q4, q5)
        system.add_speeds(u1, u2, u3)
        system.add_speeds(u4, u5, independent=False)
        system.add_kdes(*kd)
        system.add_nonholonomic_constraints(*vc)
        system.add_bodies(disc)
        system.add_loads(me.Force(Dmc, gravity[1]))
        return system, O, vc
    km = me.KanesMethod(N, q_ind=[q1, q2, q3, q4, q5], u_ind=[u1, u2, u3], u_dependent=[u4, u5],
                        velocity_constraints=vc, kd_eqs=kd)
    km.kanes_equations([disc], [gravity])
    return km, O, vc


def sympy_rhs(km):
    """KanesMethod.rhs() as a numpy function of (q, u) at VALUES."""
    syms = [*km.q, *km.u, *sp.symbols("r m g")]
    f = sp.lambdify(syms, km.rhs(), "numpy")
    return lambda y: np.asarray(f(*y, VALUES["r"], VALUES["m"], VALUES["g"]), dtype=float).ravel()


def consistent_state(km, vc, q, u_ind):
    """(q, u) with the dependent speeds solved from the velocity constraints."""
    dep = list(km.u[len(u_ind):])
    sol = sp.solve([sp.sympify(c).xreplace(km.kindiffdict()) for c in vc], dep, dict=True)[0]
    f = sp.lambdify([*km.q, *km.u[:len(u_ind)], *sp.symbols("r m g")], [sol[w] for w in dep])
    u_dep = f(*q, *u_ind, VALUES["r"], VALUES["m"], VALUES["g"])
    return np.array([*q, *u_ind, *u_dep], dtype=float)


STATES = [[0.3, 0.4, -0.7, 1.1, -0.6, 2.0], [-1.2, 0.9, 2.5, -0.4, 3.0, 0.7], [0.0, -0.2, 0.1, 0.05, 6.0, -1.5]]


def test_rolling_disc_rhs_agrees_with_kanes_method_rhs():
    km, _ = rolling_disc()
    cm = lcg.compile_model(km, values={sp.Symbol(k): v for k, v in VALUES.items()})  # by symbol or by name
    assert (cm.nq, cm.nv) == (3, 3)
    assert cm.code.state_names == ["q1", "q2", "q3", "u1", "u2", "u3"]
    ref = sympy_rhs(km)
    for y in STATES:
        a, b = cm.rhs(0.0, np.array(y)), ref(y)
        assert np.abs(a - b).max() <= 1e-12 * max(1.0, np.abs(b).max())


def test_rolling_disc_simulation_agrees_with_scipy_on_kanes_rhs():
    km, C = rolling_disc()
    ref = sympy_rhs(km)
    times = np.linspace(0.0, 4.0, 41)
    y0 = np.array(STATES[0])
    sol = solve_ivp(lambda _t, y: ref(y), (0.0, 4.0), y0, method="DOP853", rtol=1e-13, atol=1e-13, t_eval=times)
    model = mechanics.from_kanes_method(km, parameters={sp.Symbol("r"): 0.5, "m": 2.0, "g": 9.81}, origin=C)
    cm = lcg.compile_model(model, outputs=["energy", "kinetic_energy", "potential_energy"])
    res = cm.simulate(times, q0=y0[:3], v0=y0[3:], rtol=1e-12, atol=1e-12)
    assert np.abs(res.y[:, :6] - sol.y.T).max() < 1e-8
    # T from the disc's kinetic energy in (q, u), V = m g r cos(q2) from gravity and the contact
    # point (which stays at height 0): a rolling disc keeps its energy
    assert res.drift("energy") < 1e-9
    q2 = res["q2"]
    np.testing.assert_allclose(res["potential_energy"], 2.0 * 9.81 * 0.5 * np.cos(q2), rtol=1e-12)


def test_rolling_disc_equations_are_the_kanes_method_ones():
    km, _ = rolling_disc()
    with pytest.warns(UserWarning, match=r"parameter\(s\) g, m, r have no value"):
        eom = lcg.derive(km)
    m, r = sp.symbols("m r")
    assert eom.general and eom.symmetric
    assert sp.simplify(eom.M - sp.diag(5 * m * r**2 / 4, 3 * m * r**2 / 2, m * r**2 / 4)) == sp.zeros(3)
    u = sp.symbols("u1 u2 u3")
    forcing = km.forcing.xreplace({w: s for w, s in zip(km.u, u)}).xreplace(
        {qf: sp.Symbol(qf.func.__name__) for qf in km.q})
    assert sp.simplify(eom.F - forcing) == sp.zeros(3, 1)
    assert [sp.simplify(k - e) for k, e in zip(eom.model.kinematics, [u[2] / sp.cos(sp.Symbol("q2")), u[0],
                                                                       u[1] - u[2] * sp.tan(sp.Symbol("q2"))])] \
        == [0, 0, 0]


def test_dependent_speeds_rhs_agrees_with_kanes_method_rhs():
    km, O, vc = disc_with_dependent_speeds()
    assert km.mass_matrix.shape == (5, 5)  # the two acceleration-constraint rows included
    model = mechanics.from_kanes_method(km, parameters=VALUES, origin=O)
    eom = lcg.derive(model)
    assert not eom.symmetric  # the constraint rows: solved by LU
    cm = lcg.compile_model(model, outputs=["energy", "positions"])
    assert "goto lu;" in cm.code.files[cm.code.source_name]
    ref = sympy_rhs(km)
    for s in STATES:
        y = consistent_state(km, vc, s[:3] + [0.2, -0.1], s[3:])
        a, b = cm.rhs(0.0, y), ref(y)
        assert np.abs(a - b).max() <= 1e-10 * max(1.0, np.abs(b).max())
    # along a run the velocity constraints keep holding (as with sympy's own rhs) and the energy stays
    y0 = consistent_state(km, vc, [0.3, 0.4, -0.7, 0.2, -0.1], [1.1, -0.6, 2.0])
    res = cm.simulate(np.linspace(0, 3, 31), q0=y0[:5], v0=y0[5:], rtol=1e-12, atol=1e-12)
    last = res.y[-1, :10]
    assert np.abs(last - consistent_state(km, vc, last[:5], last[5:8])).max() < 1e-8
    assert res.drift("energy") < 1e-9
    # the disc's centre is a point of the model, seen from the fixed point O
    np.testing.assert_allclose(res["disc_z"], 0.5 * np.cos(res["q2"]), rtol=1e-12)


def test_system_with_dependent_speeds_is_taken_through_kane():
    system, _, _ = disc_with_dependent_speeds(as_system=True)
    km, _, vc = disc_with_dependent_speeds()
    cm = lcg.compile_model(system, values=VALUES, outputs=["energy"])
    assert cm.code.state_names == ["q1", "q2", "q3", "q4", "q5", "u1", "u2", "u3", "u4", "u5"]
    ref = sympy_rhs(km)
    for s in STATES:
        y = consistent_state(km, vc, s[:3] + [0.2, -0.1], s[3:])
        a, b = cm.rhs(0.0, y), ref(y)
        assert np.abs(a - b).max() <= 1e-10 * max(1.0, np.abs(b).max())


def test_kanes_method_refusals_name_what_is_wrong():
    km, _ = rolling_disc(form=False)
    with pytest.raises(ModelError, match=r"kanes_equations\(bodies, loads\) first"):
        lcg.compile_model(km, values=VALUES)
    km, _ = rolling_disc()
    with pytest.raises(ModelError, match=r"no value given for parameter\(s\) g "):
        lcg.compile_model(km, values={"r": 0.5, "m": 2.0})
    with pytest.raises(ModelError, match=r"unknown parameter\(s\) mass"):
        lcg.compile_model(km, values={**VALUES, "mass": 1.0})
    # no fixed point given: the potential of gravity is not known, the kinetic energy is
    with pytest.raises(ModelError, match=r"output 'energy': the potential energy .* not known: the constant force "
                                         r"at point Dmc .*origin="):
        lcg.compile_model(km, values=VALUES, outputs=["energy"])
    lcg.compile_model(km, values=VALUES, outputs=["kinetic_energy", "momenta"])
    eom = lcg.derive(mechanics.from_kanes_method(km, parameters=VALUES))
    with pytest.raises(ModelError, match="dissipation function .* not known"):
        eom.D


def test_stray_dynamicsymbols_and_accelerations_are_named():
    q, u, f = me.dynamicsymbols("q u f")
    m = sp.symbols("m")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", q * N.x)
    P.set_vel(N, u * N.x)
    km = me.KanesMethod(N, q_ind=[q], u_ind=[u], kd_eqs=[q.diff(t) - u])
    km.kanes_equations([me.Particle("p", P, m)], [(P, f * N.x)])  # f(t): an input nobody declared
    with pytest.raises(ModelError, match=r"contains 'f' \(as f\(t\)\): not a generalized coordinate or speed"):
        lcg.compile_model(km, values={"m": 1.0})
    km2 = me.KanesMethod(N, q_ind=[q], u_ind=[u], kd_eqs=[q.diff(t) - u])
    km2.kanes_equations([me.Particle("p", P, m)], [(P, -m * u.diff(t) * N.x)])  # a force in u'
    with pytest.raises(ModelError, match=r"time derivative .* of the speed 'u'"):
        lcg.compile_model(km2, values={"m": 1.0})
    km3 = me.KanesMethod(N, q_ind=[q], u_ind=[u], kd_eqs=[q.diff(t) - u])
    km3.kanes_equations([me.Particle("p", P, m)], [(P, -m * q.diff(t, 2) * N.x)])  # a force in q''
    with pytest.raises(ModelError, match=r"derivative of order 2 of 'q'"):
        lcg.compile_model(km3, values={"m": 1.0})


def test_a_refused_constrained_system_keeps_its_message_short():
    """A System with a long nonholonomic constraint but no dependent speed: sympy's refusal is cut
    (lagcodegen.util.excerpt), the message says what to declare."""
    system, _, vc = disc_with_dependent_speeds(as_system=True)
    bare = me.System(system.frame, system.fixed_point)
    bare.add_coordinates(*system.q)
    bare.add_speeds(*system.u_ind, *system.u_dep)
    bare.add_kdes(*system.kdes)
    bare.add_nonholonomic_constraints(*[c * sum(sp.cos(k * system.q[0]) for k in range(30)) for c in vc])
    bare.add_bodies(*system.bodies)
    with pytest.raises(ModelError) as info:
        lcg.compile_model(bare, values=VALUES)
    text = str(info.value)
    assert "the System has nonholonomic constraints (" in text and "characters)" in text
    assert "independent=False" in text and len(text) < 600


def sympy_bicycle():
    """sympy's own bicycle (sympy/physics/mechanics/tests/test_kane3.py, Meijaard et al.'s benchmark
    ported from Autolev): coordinates q1, q2, q5 and the dependent pitch q4 (a configuration
    constraint), speeds u2, u3, u5 and the dependent u1, u4, u6 (three velocity constraints); the
    wheel angles are left out, their rates u3, u6 kept: 4 coordinates, 6 speeds. Its statements
    are run from sympy's test source, up to kanes_equations and the benchmark's values.
    Returns (km, the velocity constraints, the configuration constraint, values by symbol)."""
    import inspect
    import textwrap
    from sympy.physics.mechanics.tests import test_kane3
    source = textwrap.dedent(inspect.getsource(test_kane3.test_bicycle).split(":\n", 1)[1])
    head, found, rest = source.partition("(fr, frstar) = KM.kanes_equations(BL, FL)")
    values, found2, _ = rest.partition("u6: v / PaperRadFront}")
    if not found or not found2:
        pytest.fail("sympy's test_kane3.test_bicycle no longer has the statements this test runs (up to "
                    "'KM.kanes_equations(BL, FL)' and the benchmark values ending 'u6: v / PaperRadFront}'): "
                    "take its bicycle from the installed sympy again")
    scope = dict(vars(test_kane3))
    exec(head + found + values + found2, scope)
    vals = {k: float(v) for k, v in scope["val_dict"].items()
            if isinstance(k, sp.Symbol) and k.name != "v"}
    return scope["KM"], scope["conlist_speed"], scope["conlist_coord"], vals


@pytest.fixture(scope="module")
def sympy_bike():
    """sympy's bicycle (:func:`sympy_bicycle`) and its compiled model, built once for the module."""
    km, conlist_speed, conlist_coord, vals = sympy_bicycle()
    return km, conlist_speed, conlist_coord, vals, lcg.compile_model(km, values=vals)


def test_sympys_bicycle_with_dependent_speeds_agrees_with_kanes_method(sympy_bike):
    """sympy's KanesMethod.rhs() solves mass_matrix_full (y' = (q', u')) by LU; its symbolic LU
    solve of this size would take hours, so the same system is solved numerically (lambdified,
    numpy) at states that satisfy the configuration and velocity constraints: within 1e-10."""
    from scipy.optimize import brentq
    km, conlist_speed, conlist_coord, vals, cm = sympy_bike
    assert (cm.nq, cm.nv) == (4, 6)
    q, u = list(km.q), list(km.u)
    Mf = sp.lambdify(q + u, km.mass_matrix_full.xreplace(vals), "numpy", cse=True)
    Ff = sp.lambdify(q + u, km.forcing_full.xreplace(vals), "numpy", cse=True)
    hol = sp.lambdify(q, conlist_coord[0].xreplace(vals), "numpy")
    dep = list(km.u[3:])
    A, b = sp.linear_eq_to_matrix([sp.sympify(c).xreplace(km.kindiffdict()).xreplace(vals) for c in conlist_speed],
                                  dep)
    Af, bf = sp.lambdify(q + u, A, "numpy"), sp.lambdify(q + u, b, "numpy")
    rng = np.random.default_rng(1)
    for _ in range(3):
        q1, q2, q5 = rng.uniform(-0.3, 0.3, 3)
        q4 = brentq(lambda x: float(hol(q1, q2, q5, x)), -0.3, 0.6)  # the pitch that keeps both wheels down
        y = np.array([q1, q2, q5, q4, *(rng.normal(size=3) + [0, 5 / 0.3, 0]), 0.0, 0.0, 0.0])
        y[7:] = np.linalg.solve(np.asarray(Af(*y), float), np.asarray(bf(*y), float).ravel())
        ref = np.linalg.solve(np.asarray(Mf(*y), float), np.asarray(Ff(*y), float).ravel())
        assert np.abs(cm.rhs(0.0, y) - ref).max() <= 1e-10 * max(1.0, np.abs(ref).max())


def test_sympys_bicycle_simulation_agrees_with_the_native_whipple_bicycle(sympy_bike):
    """sympy's bicycle (Kane's method, dependent speeds solved inside, z up) and lagcodegen's own
    Whipple bicycle (tests/helpers.py, the paper's axes: z down; reduced to independent speeds)
    at 5 m/s with a lean-rate kick of 0.5 rad/s, 5 s at rtol 1e-11: the same motion. Lean and steer
    (rotations about forward axes) agree; yaw and pitch (about the vertical and the lateral axis,
    which point the other way in sympy's frame) agree with their signs flipped."""
    from helpers import whipple_bicycle, whipple_straight_run
    km, conlist_speed, _, vals, cm = sympy_bike
    speed, kick = 5.0, 0.5
    q, u, dep = list(km.q), list(km.u), list(km.u[3:])
    A, b = sp.linear_eq_to_matrix([sp.sympify(c).xreplace(km.kindiffdict()).xreplace(vals) for c in conlist_speed],
                                  dep)
    y = np.array([0, 0, 0, 0, kick, speed / 0.3, 0, 0, 0, 0], dtype=float)  # q1 q2 q5 q4, u2 u3 u5 (u1 u4 u6)
    y[7:] = np.linalg.solve(np.asarray(sp.lambdify(q + u, A)(*y), float),
                            np.asarray(sp.lambdify(q + u, b)(*y), float).ravel())
    t = np.linspace(0.0, 5.0, 51)
    theirs = cm.simulate(t, q0=y[:4], v0=y[4:], rtol=1e-11, atol=1e-12)

    bike = whipple_bicycle()
    ours = lcg.compile_constrained(bike, "minimal")
    q0, v0 = whipple_straight_run(speed)
    ind = ours.choose(q0)
    Am, A0 = ours._matrix(ours._A, q0, 0.0, None), ours._matrix(ours._A0, q0, 0.0, None).ravel()
    v = np.array(v0, dtype=float)
    v[3] = kick  # the lean rate; the dependent rates from the constraints
    rest = [i for i in range(8) if i not in ind]
    v[rest] = np.linalg.solve(Am[:, rest], -(Am[:, ind] @ v[ind] + A0))
    mine = ours.simulate(t, q0=q0, v0=v, rtol=1e-11, atol=1e-12)
    assert np.ptp(mine["phi"]) > 0.1 and np.ptp(mine["delta"]) > 0.1  # it leans and steers
    for name, native, sign in (("q2", "phi", 1), ("q5", "delta", 1), ("q1", "psi", -1), ("q4", "theta", -1)):
        assert np.abs(theirs[name] - sign * mine[native]).max() < 1e-9, name


def test_equations_given_directly_add_to_a_lagrangian_model():
    """Model.equations_of_motion on a model with bodies: its M and F are added to Lagrange's (a
    torque tau as a given F equals the generalized force tau), energies as given."""
    def pendulum(given):
        m = lcg.Model("given_torque" if given else "q_star_torque")
        th, = m.coordinates("theta")
        l, g, mass, tau = m.parameters(l=0.8, g=9.81, m=1.3, tau=0.7)
        m.particle("bob", mass, (l * sp.sin(th), -l * sp.cos(th)))
        m.gravity(g)
        if given:
            m.equations_of_motion([[0]], [tau], kinetic_energy=0, potential_energy=0, label="motor")
        else:
            m.generalized_force(th, tau)
        return m
    a, b = lcg.compile_model(pendulum(True), outputs=["energy"]), lcg.compile_model(pendulum(False))
    for y in ([0.3, -1.0], [2.0, 0.5]):
        np.testing.assert_allclose(a.rhs(0.0, np.array(y)), b.rhs(0.0, np.array(y)), rtol=1e-14, atol=1e-14)
    with pytest.raises(ModelError, match="mass matrix of 'motor' is 2 x 2, the model has 1 speeds"):
        pendulum(False).equations_of_motion(sp.eye(2), [0, 0], label="motor")


def test_a_mass_matrix_that_is_not_symmetric_is_solved_by_lu():
    m = lcg.Model("not_symmetric")
    a, b = m.coordinates("a b")
    m.equations_of_motion([[1, 1], [0, 2]], [-a, -b])
    eom = lcg.derive(m)
    assert not eom.symmetric and not m.general
    cm = lcg.compile_model(m)  # jacobian=None: none for it
    # [1 1; 0 2] v' = (-a, -b): v2' = -b/2, v1' = -a + b/2 (not the symmetric [1 1; 1 2]'s answer)
    np.testing.assert_allclose(cm.rhs(0.0, np.array([1.0, 4.0, 0.0, 0.0])), [0, 0, 1.0, -2.0], atol=1e-15)
    with pytest.raises(ModelError, match="not symmetric.*jacobian=False"):
        lcg.compile_model(m, jacobian=True)
    with pytest.raises(ModelError, match="not symmetric.*Fortran backend"):
        lcg.compile_model(m, lang="fortran")


def test_auxiliary_speeds_are_left_out_as_kanes_method_leaves_them():
    """sympy's rolling disc with auxiliary speeds u4, u5 at the contact point (test_kane.py's
    test_aux) and the contact forces f1, f2 on them: the same motion as without them."""
    q1, q2, q3, u1, u2, u3 = me.dynamicsymbols("q1 q2 q3 u1 u2 u3")
    u4, u5, f1, f2 = me.dynamicsymbols("u4 u5 f1 f2")
    r, m, g = sp.symbols("r m g")
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [q1, N.z])
    L = Y.orientnew("L", "Axis", [q2, Y.x])
    R = L.orientnew("R", "Axis", [q3, L.y])
    w_R_N_qd = R.ang_vel_in(N)
    R.set_ang_vel(N, u1 * L.x + u2 * L.y + u3 * L.z)
    C = me.Point("C")
    C.set_vel(N, u4 * L.x + u5 * (Y.z ^ L.x))
    Dmc = C.locatenew("Dmc", r * L.z)
    Dmc.v2pt_theory(C, N, R)
    disc = me.RigidBody("disc", Dmc, R, m, (me.inertia(L, m / 4 * r**2, m / 2 * r**2, m / 4 * r**2), Dmc))
    km = me.KanesMethod(N, q_ind=[q1, q2, q3], u_ind=[u1, u2, u3],
                        kd_eqs=[me.dot(R.ang_vel_in(N) - w_R_N_qd, uv) for uv in L], u_auxiliary=[u4, u5])
    km.kanes_equations([disc], [(Dmc, -m * g * Y.z), (C, f1 * L.x + f2 * (Y.z ^ L.x))])
    cm = lcg.compile_model(km, values=VALUES, outputs=["kinetic_energy"])
    ref = sympy_rhs(rolling_disc()[0])
    for y in STATES:
        assert np.abs(cm.rhs(0.0, np.array(y)) - ref(y)).max() <= 1e-12 * max(1.0, np.abs(ref(y)).max())
