"""Integration against independent facts: analytic solutions, conserved energy, a second backend."""

import math

import numpy as np
import sympy as sp
import pytest
from scipy.special import ellipk

import lagcodegen as lcg
from lagcodegen import LagcodegenError, SingularMassMatrixError, SolverError, systems


@pytest.fixture(scope="module")
def oscillator():
    return lcg.compile_model(systems.damped_driven_oscillator(), outputs=["energy", "dissipation"])


@pytest.fixture(scope="module")
def double_pendulum():
    return lcg.compile_model(systems.double_pendulum(), outputs=["energy"])


def oscillator_exact(t, m, k, c, F0, w, x0, v0):
    """m x'' + c x' + k x = F0 cos(w t), underdamped: homogeneous + particular solution."""
    D = (k - m * w**2) ** 2 + (c * w) ** 2
    A, B = F0 * (k - m * w**2) / D, F0 * c * w / D
    gam = c / (2 * m)
    wd = math.sqrt(k / m - gam**2)
    C1 = x0 - A
    C2 = (v0 - B * w + gam * C1) / wd
    return np.exp(-gam * t) * (C1 * np.cos(wd * t) + C2 * np.sin(wd * t)) + A * np.cos(w * t) + B * np.sin(w * t)


@pytest.mark.parametrize("backend", ["native", "sksundae"])
@pytest.mark.parametrize("method", ["adams", "bdf"])
def test_damped_driven_oscillator_matches_analytic_solution(oscillator, backend, method):
    t = np.linspace(0, 30, 601)
    res = oscillator.simulate(t, q0=[0.5], v0=[-0.2], rtol=1e-10, atol=1e-12, method=method,
                              backend=backend, max_steps=10**6)
    p = res.parameters
    exact = oscillator_exact(t, p["m"], p["k"], p["c"], p["F0"], p["w"], 0.5, -0.2)
    err = np.max(np.abs(res["x"] - exact))
    print(f"{backend}/{method}: max |x - exact| = {err:.2e}")
    assert err < 1e-7


def test_runtime_parameters_change_the_solution(oscillator):
    t = np.linspace(0, 10, 201)
    params = dict(m=2.0, k=3.0, c=0.1, F0=0.0, w=1.0)
    res = oscillator.simulate(t, q0=[1.0], params=params, rtol=1e-10, atol=1e-12)
    exact = oscillator_exact(t, *params.values(), 1.0, 0.0)
    assert np.max(np.abs(res["x"] - exact)) < 1e-7


def test_pendulum_large_amplitude_period_is_the_elliptic_integral():
    cm = lcg.compile_model(systems.pendulum())
    theta0, l, g = 2.5, 1.0, 9.81
    period = 4 * math.sqrt(l / g) * ellipk(math.sin(theta0 / 2) ** 2)
    # Starting at rest at theta0, the pendulum is back at theta0, at rest, after one period.
    res = cm.simulate([0, period / 2, period], q0=[theta0], rtol=1e-11, atol=1e-12)
    assert abs(res["theta"][1] + theta0) < 1e-7
    assert abs(res["theta"][2] - theta0) < 1e-7 and abs(res["theta_dot"][2]) < 1e-6


@pytest.mark.parametrize("system,q0,v0,period", [
    ("pendulum", [1.0], [0.0], 2 * math.pi / math.sqrt(9.81)),
    ("double_pendulum", [0.6, -0.4], [0.0, 0.0], 2.0),
    ("central_potential", [1.0, 0.0], [0.0, 1.2], 2 * math.pi * (1 / (2 - 1.2**2)) ** 1.5),
])
def test_energy_is_conserved_over_100_periods(system, q0, v0, period):
    cm = lcg.compile_model(getattr(systems, system)(), outputs=["energy"])
    t = np.linspace(0, 100 * period, 2001)
    res = cm.simulate(t, q0=q0, v0=v0, rtol=1e-10, atol=1e-12)
    drift = res.drift("energy")
    print(f"{system}: T+V relative drift over 100 periods = {drift:.2e} ({res.stats['steps']} steps)")
    assert drift < 1e-6


def test_kepler_orbit_period():
    # Elliptic orbit with k = m = 1: a = 1/(2/r0 - v0^2), period 2 pi a^(3/2); r returns to r0.
    cm = lcg.compile_model(systems.central_potential())
    r0, vphi = 1.0, 1.2
    a = 1 / (2 / r0 - vphi**2)
    period = 2 * math.pi * a**1.5
    res = cm.simulate([0, period], q0=[r0, 0.0], v0=[0.0, vphi / r0], rtol=1e-11, atol=1e-12)
    assert abs(res["r"][-1] - r0) < 1e-7
    assert abs(res["phi"][-1] - 2 * math.pi) < 1e-7


def test_backends_agree_to_the_tolerance(double_pendulum):
    t = np.linspace(0, 5, 51)
    kw = dict(q0=[1.0, 0.5], rtol=1e-9, atol=1e-11)
    a = double_pendulum.simulate(t, backend="native", **kw)
    b = double_pendulum.simulate(t, backend="sksundae", **kw)
    assert a.stats["rhs_evals"] == b.stats["rhs_evals"]  # same solver, same work
    np.testing.assert_allclose(a.y, b.y, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a["energy"], b["energy"], atol=1e-12)


def test_difference_quotient_jacobian_gives_the_same_trajectory(double_pendulum):
    t = np.linspace(0, 5, 51)
    a = double_pendulum.simulate(t, q0=[1.0, 0.5], method="bdf", rtol=1e-10, atol=1e-12, jacobian=True)
    b = double_pendulum.simulate(t, q0=[1.0, 0.5], method="bdf", rtol=1e-10, atol=1e-12, jacobian=False)
    assert a.stats["jac_evals"] > 0 and a.stats["rhs_evals_dq"] == 0 and b.stats["rhs_evals_dq"] > 0
    assert np.max(np.abs(a.y - b.y)) < 1e-6


def test_result_access_by_name(double_pendulum):
    res = double_pendulum.simulate([0, 1], q0={"theta1": 0.3}, v0={"theta2": 0.1})
    assert res["theta1"][0] == 0.3 and res["theta2_dot"][0] == 0.1
    assert set(res.q) == {"theta1", "theta2"} and res.v["theta2"][0] == 0.1
    assert res.success and res.status == 0 and res.message == "success"
    with pytest.raises(KeyError, match="nope"):
        res["nope"]


# ---------------------------------------------------------------------------- failures
def test_too_many_steps_reports_time_reached(double_pendulum):
    with pytest.raises(SolverError, match="too many steps") as info:
        double_pendulum.simulate([0, 100], q0=[1.0, 0.5], max_steps=50)
    assert 0 < info.value.t < 100
    assert info.value.result.t[-1] <= info.value.t


def test_partial_result_without_raising(double_pendulum):
    res = double_pendulum.simulate([0, 100], q0=[1.0, 0.5], max_steps=50, raise_on_error=False)
    assert not res.success and res.status == -1 and len(res.t) < 1001


def test_tolerance_too_tight(double_pendulum):
    with pytest.raises(SolverError) as info:
        double_pendulum.simulate([0, 1], q0=[1.0, 0.5], rtol=1e-30, atol=1e-30)
    assert "tolerance" in str(info.value).lower() or "accuracy" in str(info.value).lower()


def singular_model():
    # T = (sin x)^2 x'^2 / 2: M vanishes at x = 0.
    model = lcg.Model("singular")
    x, = model.coordinates("x")
    model.kinetic_energy(sp.sin(x) ** 2 * model.dot(x) ** 2 / 2)
    model.potential_energy(-x)
    return model


def test_singular_mass_matrix_at_initial_state():
    cm = lcg.compile_model(singular_model())
    with pytest.raises(SingularMassMatrixError, match="singular at the initial state") as info:
        cm.simulate([0, 1], q0=[0.0])
    assert info.value.t == 0.0


@pytest.mark.parametrize("backend", ["native", "sksundae"])
def test_singular_mass_matrix_during_integration(backend):
    # Released at x = -1 with force pushing toward x = 0 where M = 0 (finite-time arrival).
    cm = lcg.compile_model(singular_model())
    with pytest.raises(SolverError) as info:
        cm.simulate([0, 5], q0=[-1.0], backend=backend)
    assert 0 < info.value.t < 5


def test_bad_arguments(double_pendulum):
    with pytest.raises(LagcodegenError, match="y0 has 3 values"):
        double_pendulum.simulate([0, 1], y0=[1, 2, 3])
    with pytest.raises(LagcodegenError, match="unknown coordinate"):
        double_pendulum.simulate([0, 1], q0={"phi": 1.0})
    with pytest.raises(LagcodegenError, match="not a run-time parameter"):
        double_pendulum.simulate([0, 1], params={"mass": 1.0})
    with pytest.raises(lcg.ModelError, match="finite"):
        double_pendulum.simulate([0, 1], params={"g": float("nan")})
    with pytest.raises(LagcodegenError, match="increasing"):
        double_pendulum.simulate([1, 0])
    with pytest.raises(LagcodegenError, match="method"):
        double_pendulum.simulate([0, 1], method="rk4")


def test_diagonal_mass_matrix_solve_and_its_singularity():
    # Polar coordinates: M = diag(m, m r^2) is structurally diagonal, so the generated solve
    # divides instead of factoring; at r = 0 it is singular.
    from lagcodegen.formulation.kernels import mass_matrix_is_diagonal
    model = systems.central_potential()
    assert mass_matrix_is_diagonal(lcg.derive(model))
    cm = lcg.compile_model(model)
    y = np.array([1.3, 0.4, 0.2, 0.7])  # r, phi, r', phi'
    r, _, rd, phid = y
    expected = [r * phid**2 - 1 / r**2, -2 * rd * phid / r]  # m = k = 1
    np.testing.assert_allclose(cm.rhs(0.0, y)[2:], expected, rtol=1e-15)
    with pytest.raises(SingularMassMatrixError, match="initial state"):
        cm.simulate([0, 1], q0=[0.0, 0.0], v0=[1.0, 0.0])


def test_fixed_point_iteration_needs_no_jacobian(double_pendulum):
    t = np.linspace(0, 5, 51)
    newton = double_pendulum.simulate(t, q0=[1.0, 0.5], rtol=1e-10, atol=1e-12)
    fixed = double_pendulum.simulate(t, q0=[1.0, 0.5], rtol=1e-10, atol=1e-12, linear_solver="fixedpoint")
    assert fixed.stats["jac_evals"] == 0 and fixed.stats["lin_setups"] == 0 and fixed.stats["rhs_evals_dq"] == 0
    assert np.max(np.abs(fixed.y - newton.y)) < 1e-7
    with pytest.raises(LagcodegenError, match="needs backend='native'"):
        double_pendulum.simulate(t, q0=[1.0, 0.5], linear_solver="fixedpoint", backend="sksundae")


# ---------------------------------------------------------------------- inputs refused before the solver
@pytest.fixture(scope="module")
def log_output():
    """A harmonic oscillator with the outputs log(x) and sqrt(x): not finite at x <= 0."""
    m = lcg.Model("logout")
    x, = m.coordinates("x")
    k, = m.parameters(k=1.0)
    m.particle("b", 1.0, (x, 0))
    m.potential_energy(k * x**2 / 2)
    m.output("log_x", sp.log(x))
    m.output("sqrt_x", sp.sqrt(x))
    return lcg.compile_model(m, outputs=["energy", "log_x", "sqrt_x"])


@pytest.mark.parametrize("options", [dict(), dict(backend="sksundae"), dict(method="bdf"), dict(method="taylor")])
def test_zero_tolerances_are_refused_before_the_solver(oscillator, options):
    with pytest.raises(LagcodegenError, match="rtol and atol are both 0") as info:
        oscillator.simulate([0, 1], q0=[0.5], rtol=0, atol=0, **options)
    assert not isinstance(info.value, SolverError)  # never reached CVODE (flag -22)
    with pytest.raises(LagcodegenError, match="rtol and atol are both 0.*state 1"):
        oscillator.simulate([0, 1], q0=[0.5], rtol=0, atol=[1e-8, 0.0])
    assert oscillator.simulate([0, 1], q0=[0.5], rtol=0, atol=1e-9).success  # either alone is fine
    assert oscillator.simulate([0, 1], q0=[0.5], v0=[0.1], rtol=1e-8, atol=0).success


@pytest.mark.parametrize("options", [dict(), dict(backend="sksundae"), dict(method="taylor")])
def test_output_not_finite_at_the_initial_state_names_it(log_output, options):
    with pytest.raises(SolverError, match=r"output not finite at the initial state: log_x = -inf") as info:
        log_output.simulate([0, 1], q0=[0.0], v0=[1.0], **options)
    assert info.value.t == 0.0
    with pytest.raises(SolverError, match=r"outputs not finite .*log_x = nan, sqrt_x = nan"):
        log_output.simulate([2.0, 3.0], q0=[-1.0], v0=[1.0], **options)
    res = log_output.simulate([0, 0.5], q0=[1.0], **options)
    assert res.success and np.isfinite(res["log_x"]).all()


@pytest.mark.parametrize("method", ["adams", "bdf"])
def test_max_steps_is_a_budget_for_the_whole_run_on_both_backends(double_pendulum, method):
    """scikit-sundae's max_num_steps counts the steps of one output interval; max_steps means
    the steps of the whole run on both backends (issue 13)."""
    t = np.linspace(0, 5, 51)
    kw = dict(q0=[1.0, 0.5], method=method, rtol=1e-8, atol=1e-10)
    native = double_pendulum.simulate(t, **kw)
    ref = double_pendulum.simulate(t, backend="sksundae", **kw)
    steps = native.stats["steps"]
    assert abs(ref.stats["steps"] - steps) < 0.1 * steps  # counted; about the same steps
    np.testing.assert_allclose(ref.y, native.y, rtol=0, atol=1e-6)
    budget = steps // 2  # more than any one interval takes, half of the run
    for backend in ("native", "sksundae"):
        with pytest.raises(SolverError, match="max_steps") as info:
            double_pendulum.simulate(t, backend=backend, max_steps=budget, **kw)
        assert info.value.flag == -1 and 0 < info.value.t < 5
        assert double_pendulum.simulate(t, backend=backend, max_steps=2 * steps, **kw).success


@pytest.fixture(scope="module")
def toward_a_singularity():
    """x'' = 1/sqrt(1 - x) from rest at 0: x reaches 1 in finite time, where the force is not
    finite (beyond it: NaN)."""
    m = lcg.Model("toward_one")
    x, = m.coordinates("x")
    m.particle("p", 1, [x, 0])
    m.generalized_force(x, 1 / sp.sqrt(1 - x))
    return lcg.compile_model(m)


@pytest.mark.parametrize("backend", ["native", "sksundae"])
@pytest.mark.parametrize("method", ["adams", "bdf"])
def test_a_right_hand_side_turning_non_finite_is_named(toward_a_singularity, method, backend):
    """Not 'corrector convergence failed' or 'too many steps' alone: the non-finite value and its
    t, or steps that no longer advance t (issue 13)."""
    with pytest.raises(SolverError) as info:
        toward_a_singularity.simulate(np.linspace(0, 5, 101), method=method, max_steps=20000, backend=backend)
    text = str(info.value)
    if backend == "sksundae":  # its CVODE: the non-finite value, or too many steps
        assert "a computed value is not finite at t = 1.333" in text or "max_steps" in text, text
        return
    assert "a computed value is not finite at t = 1.333" in text or \
        "the step size fell below the resolution of t at t = 1.333" in text, text
    assert 1.33 < info.value.t < 1.334
    if method == "bdf":
        assert "a computed value is not finite at t = 1.333" in text and "corrector" not in text


# ---------------------------------------------------------------------- pickling
@pytest.fixture(scope="module")
def chain():
    return lcg.compile_model(systems.n_link_pendulum(10), outputs=["energy"])


def test_a_pickle_carries_the_generated_code_not_the_scene(chain):
    """A 10-link chain pickles to about its C sources (it was 187 kB: the scene pickled, twice
    over); unpickled, it runs bit-identically, and what needs the scene says so."""
    import pickle
    data = pickle.dumps(chain)
    sources = sum(len(text) for text in chain.code.files.values())
    assert len(data) < sources + 16_000
    assert len(data) < len(pickle.dumps(chain.code.scene)) / 4
    back = pickle.loads(data)
    assert back.code.scene is None and chain.code.scene is not None  # the model pickled keeps its scene
    assert (back.state_names, back.param_names, back.output_names) == (chain.state_names, chain.param_names,
                                                                        chain.output_names)
    t = np.linspace(0.0, 2.0, 21)
    q0 = np.linspace(0.1, 1.0, 10)
    mine, theirs = back.simulate(t, q0=q0, params={"g": 9.7}), chain.simulate(t, q0=q0, params={"g": 9.7})
    assert np.array_equal(mine.y, theirs.y) and np.array_equal(mine["energy"], theirs["energy"])
    with pytest.raises(LagcodegenError, match=r"method='taylor' needs the symbolic scene .*with_scene"):
        back.simulate(t, q0=q0, method="taylor")
    with pytest.raises(LagcodegenError, match="sensitivities needs the symbolic scene"):
        back.simulate(t, q0=q0, sensitivities=["g"])


def test_with_scene_pickles_the_scene_once_and_the_taylor_method_runs():
    import pickle
    from lagcodegen.simulation.ode import with_scene
    cm = lcg.compile_model(systems.n_link_pendulum(3))
    data = pickle.dumps(with_scene(cm))
    assert len(data) < len(pickle.dumps(cm.code.scene)) + len(pickle.dumps(cm)) + 4_000
    back = pickle.loads(data)
    assert back.code.scene is not None
    t = np.linspace(0.0, 1.0, 11)
    assert np.array_equal(back.simulate(t, q0=[0.3, 0.2, 0.1], method="taylor").y,
                          cm.simulate(t, q0=[0.3, 0.2, 0.1], method="taylor").y)
    with pytest.raises(LagcodegenError, match="no symbolic scene to carry"):
        with_scene(pickle.loads(pickle.dumps(lcg.compile_model(systems.n_link_pendulum(4)))))


def double_pendulum_accelerations(y, l1=1.0, l2=1.0, m1=1.0, m2=1.0, g=9.81):
    """The point-mass double pendulum's angular accelerations, closed form (Lagrange's equations
    solved by hand)."""
    t1, t2, w1, w2 = y
    d = t1 - t2
    den = 2 * m1 + m2 - m2 * math.cos(2 * d)
    a1 = (-g * (2 * m1 + m2) * math.sin(t1) - m2 * g * math.sin(t1 - 2 * t2)
          - 2 * math.sin(d) * m2 * (w2 ** 2 * l2 + w1 ** 2 * l1 * math.cos(d))) / (l1 * den)
    a2 = 2 * math.sin(d) * (w1 ** 2 * l1 * (m1 + m2) + g * (m1 + m2) * math.cos(t1)
                            + w2 ** 2 * l2 * m2 * math.cos(d)) / (l2 * den)
    return np.array([w1, w2, a1, a2])


def test_rhs_every_form_of_state_and_out(double_pendulum):
    """rhs's direct path (a float64 array of shape (ny,)) and its general one (lists, other
    dtypes, strided views, parameters given) give the closed-form accelerations; a native=False
    build (its own module, no runtime table) the same; a wrong state or out array is refused by
    name, never handed to C."""
    cm = double_pendulum
    y = np.array([0.7, -1.1, 0.4, 2.3])
    exact = double_pendulum_accelerations(y)
    np.testing.assert_allclose(cm.rhs(0.0, y), exact, rtol=1e-14, atol=1e-14)
    strided = np.empty(8)
    strided[::2] = y
    assert np.array_equal(cm.rhs(0.0, strided[::2]), cm.rhs(0.0, y))
    assert np.array_equal(cm.rhs(0, list(y)), cm.rhs(0.0, y))
    y32 = y.astype(np.float32)
    np.testing.assert_allclose(cm.rhs(0.0, y32), double_pendulum_accelerations([float(x) for x in y32]), rtol=1e-14,
                               atol=1e-14)
    p = cm.parameter_vector({"g": 3.0, "m2": 2.5})
    np.testing.assert_allclose(cm.rhs(0.0, y, p), double_pendulum_accelerations(y, m2=2.5, g=3.0), rtol=1e-14,
                               atol=1e-14)
    out = np.full(4, np.nan)
    assert cm.rhs(0.0, y, out=out) is out and np.array_equal(out, cm.rhs(0.0, y))
    own = lcg.build_code(lcg.generate_c(lcg.Scene(lcg.derive(systems.double_pendulum("dp_own_module")),
                                                  prefix="dp_own_module")), native=False)
    assert own.table is None and np.array_equal(own.rhs(0.0, y), cm.rhs(0.0, y))
    assert np.array_equal(own.rhs(0.0, y, p), cm.rhs(0.0, y, p))
    readonly = np.empty(4)
    readonly.flags.writeable = False
    for bad in (np.empty(3), np.empty(4, dtype=np.float32), np.empty(8)[::2], readonly, [0.0] * 4):
        with pytest.raises(LagcodegenError, match="out must be a writable, C-contiguous float64 array of shape"):
            cm.rhs(0.0, y, out=bad)
    for bad in (np.zeros(3), np.zeros(5), [1.0, 2.0], None, "abcd"):
        with pytest.raises(LagcodegenError, match=r"y (must be an array of 4 real numbers|has \d+ values, expected 4)"):
            cm.rhs(0.0, bad)
    with pytest.raises(LagcodegenError, match="p has 2 values, expected 5"):
        cm.rhs(0.0, y, [1.0, 2.0])
