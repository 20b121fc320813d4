"""Bundles of constrained systems with contacts: the contact functions and their impact law in the
bundle's C, driven by its RK4 example (impacts located by bisection within a step, persistent
contact, release), built with make (strict flags, `make check` against reference.csv) and CMake,
checked against the closed-form bouncing ball and Newton's cradle (the facts tests/test_impacts.py
checks the impact driver with). Contacts with Coulomb friction: the example drives the runtime's
friction core (lcg_imp_fric.c, shipped as it is), checked against the block on an incline, the
sphere with backspin, the frictional impact of a disc, the particle launched across a 3-D incline
(scipy's DOP853 on its closed form), the ladder and Painleve's rod (the systems of
tests/test_friction.py and tests/test_friction_speeds.py, imported: their builders compile them,
``.system`` is the ConstrainedSystem; the bundles' reference runs compile the same code, cached)."""

from __future__ import annotations

import math
import re
import subprocess

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.codegen.bundle import render_constrained_bundle, write_files
from lagcodegen.errors import ModelError

G = 9.81
STRICT = "-O2 -std=c99 -Wall -Wextra -Werror -pedantic"
EVENT = re.compile(r"^# t = (\S+): contact (\d+) (.+?) \(impulse (\S+), w (\S+) -> (\S+)\)$")


def _run(cmd, cwd, check=True):
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=300)
    if check:
        assert proc.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{proc.stdout}\n{proc.stderr}"
    return proc


def _events(stderr: str) -> list[tuple]:
    """(t, contact, kind, impulse, w before, w after) of the example's contact lines."""
    out = []
    for line in stderr.splitlines():
        m = EVENT.match(line)
        if m:
            t, k, kind, P, wm, wp = m.groups()
            out.append((float(t), int(k), kind, float(P), float(wm), float(wp)))
    return out


def _ball_system(e: float = 0.8, friction=None):
    m = lcg.Model("bball")
    (y,) = m.coordinates("y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    if friction is None:
        return lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=e)])
    x = m.coordinates("x")
    return lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=e, tangent=x[0], friction=friction)])


def test_bouncing_ball_bundle_checks_against_its_reference_and_bounces_as_the_closed_form(tmp_path, tools):
    e, h0 = 0.8, 1.0
    files = render_constrained_bundle(_ball_system(e), outputs=["energy"], y0=[h0, 0.0], t_end=6.0)
    assert {"bball_impact.c", "bball_dae_table.c", "bball_table.c", "bball.c", "lcg_imp_model.h",
            "reference.csv"} <= set(files)
    write_files(tmp_path, files)
    check = _run(["make", f"CFLAGS={STRICT}", "check"], tmp_path)
    assert "rk4_example agrees with reference.csv at t = 1: 5 values" in check.stdout
    # the reference is the impact driver's run: a bounce lies before t = 1
    assert "bounce" in check.stderr
    proc = _run(["./rk4_example", "-t", "6", "-n", "6000", "-e", "6000"], tmp_path)
    events = _events(proc.stderr)
    bounces = [ev for ev in events if ev[2] == "bounce"]
    assert len(bounces) >= 20
    t1 = math.sqrt(2 * h0 / G)
    k = np.arange(20)
    t_exact = t1 + 2 * t1 * e * (1 - e**k) / (1 - e)
    assert np.max(np.abs(np.array([b[0] for b in bounces[:20]]) / t_exact - 1)) < 1e-9
    w_after = np.array([b[5] for b in bounces[:20]])
    assert np.max(np.abs(w_after**2 / (2 * G) / (h0 * e ** (2 * (k + 1))) - 1)) < 1e-9
    for b in bounces[:20]:  # Newton's law and the impulse m (1 + e) |w-|
        assert b[5] == pytest.approx(-e * b[4], rel=1e-12) and b[3] == pytest.approx(-(1 + e) * b[4], rel=1e-12)
    # accumulation at t1 (1 + e) / (1 - e): persistent contact from at most 2 (speed / e) / (g (1 - e)) before
    sticks = [ev for ev in events if ev[2] == "impact into persistent contact"]
    t_zeno = t1 * (1 + e) / (1 - e)
    assert len(sticks) == 1 and t_zeno - 2 * (1e-6 / e) / (G * (1 - e)) - 1e-9 <= sticks[0][0] <= t_zeno + 1e-9
    header, final = proc.stdout.splitlines()[0].split(","), np.array(proc.stdout.splitlines()[-1].split(","), float)
    assert header == ["t", "y", "y_dot", "energy", "lambda_ineq_0"]
    assert abs(final[1]) < 1e-9 and abs(final[2]) < 1e-9 and final[4] == pytest.approx(G, rel=1e-9)
    # a reference the example does not meet fails make check, naming the value
    ref = (tmp_path / "reference.csv").read_text().splitlines()
    (tmp_path / "reference.csv").write_text("\n".join(ref[:-1] + [ref[-1].replace(ref[-1].split(",")[1], "0.5", 1)])
                                            + "\n")
    failed = _run(["make", "check"], tmp_path, check=False)
    assert failed.returncode != 0 and "make check: y = " in failed.stdout


def test_newtons_cradle_bundle_with_cmake(tmp_path, tools):
    m = lcg.Model("bcradle")
    xs = m.coordinates("x1 x2 x3")
    m.parameters(m=1.0, d=0.1)
    for i, x in enumerate(xs):
        m.particle(f"b{i}", sp.Symbol("m"), (x, 0))
    d = sp.Symbol("d")
    system = lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(xs[1] - xs[0] - d, restitution=1.0),
                                                    lcg.Inequality(xs[2] - xs[1] - d, restitution=1.0)])
    gap = 1e-3
    y0 = [0.0, 0.1 + gap, 0.2 + 2 * gap, 1.0, 0.0, 0.0]
    write_files(tmp_path, render_constrained_bundle(system, outputs=["energy"], y0=y0, t_end=1.0))
    _run(["cmake", "-S", ".", "-B", "build", f"-DCMAKE_C_FLAGS={STRICT}"], tmp_path)
    _run(["cmake", "--build", "build"], tmp_path)
    proc = _run([str(tmp_path / "build" / "rk4_example"), "-t", "1", "-n", "1000", "-e", "1"], tmp_path)
    events = _events(proc.stderr)
    assert [(ev[1], ev[2]) for ev in events] == [(0, "bounce"), (1, "bounce")]
    assert events[0][0] == pytest.approx(gap, rel=1e-10) and events[1][0] == pytest.approx(2 * gap, rel=1e-10)
    rows = np.array([r.split(",") for r in proc.stdout.splitlines()[1:]], dtype=float)
    v = rows[-1, 4:7]
    assert abs(v[0]) < 1e-12 and abs(v[1]) < 1e-12 and abs(v[2] - 1.0) < 1e-12
    assert np.max(np.abs(rows[:, 4:7].sum(axis=1) - 1.0)) < 1e-12  # momentum
    assert np.max(np.abs(rows[:, 7] - 0.5)) < 1e-12  # energy (e = 1)


def test_pendulum_at_a_wall_bundle_with_an_equality_constraint(tmp_path, tools):
    """A pendulum in Cartesian coordinates (x^2 + y^2 = l^2, a multiplier) released from 1 rad
    against the wall x >= 0 (e = 0.8): its impacts at T(1)/4, then every half period T(a_k)/2 of
    the amplitude after impact k (cos a_k = 1 - l w_k^2 / (2 g), w_k = e^k w_0,
    T(a) = 4 sqrt(l/g) K(sin^2(a/2))), Newton's law at each, and make check against the impact
    driver (the constraint's multiplier lambda_0 among the values)."""
    from scipy.special import ellipk
    m = lcg.Model("pwall")
    x, y = m.coordinates("x y")
    m.parameters(g=G, m=1.0, l=1.0)
    m.particle("b", sp.Symbol("m"), (x, y))
    m.gravity(sp.Symbol("g"))
    system = lcg.ConstrainedSystem(m, holonomic=[x**2 + y**2 - sp.Symbol("l") ** 2],
                                   inequalities=[lcg.Inequality(x, restitution=0.8)])
    files = render_constrained_bundle(system, y0=[math.sin(1.0), -math.cos(1.0), 0.0, 0.0], t_end=3.0)
    write_files(tmp_path, files)
    check = _run(["make", f"CFLAGS={STRICT}", "check"], tmp_path)
    assert "rk4_example agrees with reference.csv at t = 1: 10 values" in check.stdout
    assert "lambda_0" in (tmp_path / "reference.csv").read_text()
    bounces = [ev for ev in _events(_run(["./rk4_example"], tmp_path).stderr) if ev[2] == "bounce"]

    def period(a):
        return 4 * math.sqrt(1 / G) * float(ellipk(math.sin(a / 2) ** 2))
    t, w, exact = period(1.0) / 4, math.sqrt(2 * G * (1 - math.cos(1.0))), []
    for _ in bounces:
        exact.append(t)
        w *= 0.8
        t += period(math.acos(1 - w * w / (2 * G))) / 2
    assert len(bounces) == 3
    assert np.max(np.abs(np.array([b[0] for b in bounces]) / exact - 1)) < 1e-9
    for b in bounces:
        assert b[5] == pytest.approx(-0.8 * b[4], rel=1e-10)


def test_no_slip_contact_with_two_tangents_bundle(tmp_path, tools):
    """A no-slip contact with two tangents (a particle dropped from z = 1 moving at (1, 0.5) onto a
    rough floor, e = 0.5) has two tangential rows in the contact table, which the example counts:
    the impact at sqrt(2 / g) stops the sliding (x, y held there), make check against the impact
    driver."""
    m = lcg.Model("bnoslip3")
    x, y, z = m.coordinates("x y z")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (x, y, z))
    m.gravity(sp.Symbol("g"))
    system = lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(z, restitution=0.5, tangent=(x, y))])
    files = render_constrained_bundle(system, outputs=["energy"], y0=[0.0, 0.0, 1.0, 1.0, 0.5, 0.0], t_end=2.0)
    assert "#define NROW 3" in files["rk4_example.c"]
    write_files(tmp_path, files)
    _run(["make", f"CFLAGS={STRICT}", "check"], tmp_path)
    proc = _run(["./rk4_example", "-e", "2000"], tmp_path)
    t1 = math.sqrt(2 / G)
    events = _events(proc.stderr)
    assert events[0][2] == "bounce" and events[0][0] == pytest.approx(t1, rel=1e-10)
    final = np.array(proc.stdout.splitlines()[-1].split(","), float)
    assert final[1] == pytest.approx(t1, rel=1e-10) and final[2] == pytest.approx(0.5 * t1, rel=1e-10)
    assert abs(final[4]) < 1e-12 and abs(final[5]) < 1e-12


def test_contact_bundles_refuse_what_they_do_not_carry():
    with pytest.raises(ModelError, match="contacts are made in C only"):
        render_constrained_bundle(_ball_system(), "fortran", outputs=["energy"], reference=False)
    # friction too: the contact functions and the friction core are C
    with pytest.raises(ModelError, match="contacts are made in C only"):
        render_constrained_bundle(_ball_system(friction=0.5), "fortran", outputs=["energy"], reference=False)
    with pytest.raises(ModelError, match="index-1 formulation, not GGL"):
        render_constrained_bundle(_ball_system(friction=0.5), outputs=["energy"], ggl=True, reference=False)


def test_contact_bundle_ships_the_runtime_impact_law_as_it_is():
    """The example's impact law is the runtime's lcg_imp_law.c (the file the impact drivers use),
    shipped unchanged and compiled into the library, not a copy in the example."""
    from lagcodegen.runtime import source
    files = render_constrained_bundle(_ball_system(), outputs=["energy"], reference=False)
    for name in ("lcg_imp_law.c", "lcg_imp_law.h"):
        assert files[name] == source(name)
    example = files["rk4_example.c"]
    assert "lcg_imp_jump(&law" in example and "lcg_imp_release_pulling(&law" in example
    assert "im->impact(" not in example
    assert "lcg_imp_law.o" in files["Makefile"] and "lcg_imp_law.c" in files["CMakeLists.txt"]


# ---------------------------------------------------------------- Coulomb friction

FRICTION_EVENT = re.compile(r"^# t = (\S+): contact (\d+) (.+?) \((impulse|lambda_t) (\S+), (w|u) (\S+) -> (\S+)\)$")
FINAL_MODE = re.compile(r"^# final mode of contact (\d+): (\S+)$")


def _friction_events(stderr: str) -> list[tuple]:
    """(t, contact, kind, impulse or lambda_t, w or u before, after) of the friction example's lines."""
    out = []
    for line in stderr.splitlines():
        m = FRICTION_EVENT.match(line)
        if m:
            t, k, kind, _, P, _, before, after = m.groups()
            out.append((float(t), int(k), kind, float(P), float(before), float(after)))
    return out


def _final_modes(stderr: str) -> dict[int, str]:
    return {int(m.group(1)): m.group(2) for m in map(FINAL_MODE.match, stderr.splitlines()) if m}


def _table(stdout: str) -> tuple[list[str], np.ndarray]:
    lines = stdout.splitlines()
    return lines[0].split(","), np.array([row.split(",") for row in lines[1:]], dtype=float)


def _friction_bundle(tmp_path, system, y0, t_end, reference=True, **options):
    """The bundle of ``system`` written into tmp_path and built with make and the strict flags
    (`make check` against the impact driver's reference when there is one)."""
    files = render_constrained_bundle(system, y0=y0, t_end=t_end, reference=reference, **options)
    write_files(tmp_path, files)
    if reference:
        check = _run(["make", f"CFLAGS={STRICT}", "check"], tmp_path)
        assert "rk4_example agrees with reference.csv at t = " in check.stdout, check.stdout
    else:
        _run(["make", f"CFLAGS={STRICT}", "rk4_example"], tmp_path)
    return files


@pytest.mark.parametrize("alpha, mu", [(0.5, 0.6), (0.5, 0.3)])
def test_block_on_an_incline_bundle_sticks_when_tan_alpha_le_mu_else_slides_at_g_sin_minus_mu_cos(tmp_path, tools,
                                                                                               alpha, mu):
    """The example's run (RK4 at h = 1e-3, started at rest) against the closed form: sticking
    forever (x = 0, lambda_t = -m g sin(alpha)) when tan(alpha) <= mu, else x = a t^2 / 2 with
    a = g (sin(alpha) - mu cos(alpha)) to 1e-9 relative (RK4 integrates the constant acceleration
    exactly; the figure is round-off's), N = m g cos(alpha) either way."""
    from test_friction import _incline
    files = _friction_bundle(tmp_path, _incline(alpha, mu).system, [0.0, 0.0, 0.0, 0.0], 3.0, outputs=["energy"])
    assert "lcg_imp_fric.c" in files and "lambda_t_ineq_0" in files["reference.csv"]
    proc = _run(["./rk4_example", "-t", "3", "-n", "3000", "-e", "100"], tmp_path)
    names, rows = _table(proc.stdout)
    assert names == ["t", "x", "y", "x_dot", "y_dot", "energy", "lambda_ineq_0", "lambda_t_ineq_0"]
    t, x = rows[:, 0], rows[:, 1]
    assert np.max(np.abs(rows[:, 6] / (G * math.cos(alpha)) - 1)) < 1e-9
    assert np.max(np.abs(rows[:, 2])) < 1e-12
    assert _friction_events(proc.stderr) == []  # no transition: the mode of the start throughout
    if math.tan(alpha) <= mu:
        assert np.max(np.abs(x)) < 1e-12 and _final_modes(proc.stderr) == {0: "stick"}
        assert np.max(np.abs(rows[:, 7] + G * math.sin(alpha))) < 1e-9
    else:
        acc = G * (math.sin(alpha) - mu * math.cos(alpha))
        assert np.max(np.abs(x[1:] / (0.5 * acc * t[1:] ** 2) - 1)) < 1e-9
        assert np.max(np.abs(rows[:, 7] + mu * G * math.cos(alpha))) < 1e-9
        assert _final_modes(proc.stderr) == {0: "slip+"}
    # sent up the slope at 3 m/s: it stops at 3 / (g (sin + mu cos)), located within its step,
    # then sticks (tan(alpha) <= mu) or slides back
    proc = _run(["./rk4_example", "-t", "1", "-n", "1000", "-e", "1000", "0", "0", "-3", "0"], tmp_path)
    events = _friction_events(proc.stderr)
    t_stop = 3 / (G * (math.sin(alpha) + mu * math.cos(alpha)))
    assert len(events) == 1 and events[0][0] == pytest.approx(t_stop, rel=1e-12)
    assert events[0][2] == ("grip" if math.tan(alpha) <= mu else "reverse")


def test_sphere_with_backspin_bundle_slips_then_rolls_with_cmake(tmp_path, tools):
    """A sphere (I = 2/5 m R^2) launched at v0 with backspin w0 slips until t* = 2 (v0 + R w0) /
    (7 mu g) and rolls on at (5 v0 - 2 R w0) / 7: the example's grip and rolling speed to 1e-9,
    the friction force -mu m g while it slips, 0 after, the energy lost the friction work; built
    with CMake (strict flags), make check against the impact driver's run."""
    from test_friction import _roller
    mu, R, v0, w0 = 0.2, 0.3, 3.0, 4.0
    t_star = 2 * (v0 + R * w0) / (7 * mu * G)
    _friction_bundle(tmp_path, _roller(0.4, mu).system, [0.0, R, 0.0, v0, 0.0, w0], 2 * t_star, outputs=["energy"])
    _run(["cmake", "-S", ".", "-B", "build", f"-DCMAKE_C_FLAGS={STRICT}"], tmp_path)
    _run(["cmake", "--build", "build"], tmp_path)
    proc = _run([str(tmp_path / "build" / "rk4_example"), "-e", "10"], tmp_path)
    events = _friction_events(proc.stderr)
    assert [ev[2] for ev in events] == ["grip"], proc.stderr
    assert events[0][0] == pytest.approx(t_star, rel=1e-9)
    names, rows = _table(proc.stdout)
    col = {name: i for i, name in enumerate(names)}
    before, after = rows[:, 0] < t_star, rows[:, 0] > t_star
    v_roll = (5 * v0 - 2 * R * w0) / 7
    assert np.max(np.abs(rows[after, col["x_dot"]] / v_roll - 1)) < 1e-9
    assert np.max(np.abs(rows[after, col["x_dot"]] + R * rows[after, col["phi_dot"]])) < 1e-9 * v_roll  # rolling
    assert np.max(np.abs(rows[before, col["lambda_t_ineq_0"]] + mu * G)) < 1e-9
    assert np.max(np.abs(rows[after, col["lambda_t_ineq_0"]])) < 1e-9
    work = mu * G * (v0 + R * w0) * t_star / 2
    assert rows[0, col["energy"]] - rows[-1, col["energy"]] == pytest.approx(work, rel=1e-9)
    assert _final_modes(proc.stderr) == {0: "stick"}


def test_shaken_block_bundle_stick_slip_times(tmp_path, tools):
    """A block (m = 1) on a rough floor (mu = 0.3) pushed by A sin(w t) (A = 5, w = 3): it slips
    where the sticking force reaches mu N and grips where its velocity returns to 0, 19 transitions
    in 10 s at the closed form's times (tests/test_friction.py's _shaker_times) to 1e-12: each
    located by bisection within its RK4 step, the forcing's time dependence resolved by the fixed
    steps (make check against the impact driver)."""
    from test_friction import _shaker_times
    A, w, mu = 5.0, 3.0, 0.3
    m = lcg.Model("bshaker")
    x, y = m.coordinates("x y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (x, y))
    m.gravity(sp.Symbol("g"))
    m.generalized_force(x, A * sp.sin(w * m.t))
    floor = lcg.Inequality(y, restitution=0.0, tangent=x, friction=mu)
    _friction_bundle(tmp_path, lcg.ConstrainedSystem(m, inequalities=[floor]), [0.0, 0.0, 0.0, 0.0], 10.0)
    events = _friction_events(_run(["./rk4_example", "-e", "10000"], tmp_path).stderr)
    exact = _shaker_times(A, w, mu, 10.0)
    assert len(exact) >= 18 and [ev[2] for ev in events] == [kind for kind, _ in exact]
    assert np.max(np.abs(np.array([ev[0] for ev in events]) / np.array([t for _, t in exact]) - 1)) < 1e-12


@pytest.mark.parametrize("vx, mu, sticks", [(1.0, 0.5, True), (4.0, 0.1, False)])
def test_frictional_impact_of_a_disc_bundle_sticks_within_the_cone_else_slides_with_mu_pn(tmp_path, tools, vx, mu,
                                                                                         sticks):
    """A disc (I = m R^2 / 2) without spin hits the rough floor with (vx, -vy), e = 0.5: P_n =
    m (1 + e) |w-|; P_t = -m u / 3 (the touching point stops) when that is within mu P_n, else
    -mu P_n (x' = vx - mu P_n / m, phi' = -2 mu P_n / (m R)): the example's impact (lcg_fr_impact)
    against these to 1e-10."""
    from test_friction import _roller
    e, R, vy, h = 0.5, 0.3, 2.0, 0.1
    t_hit = (-vy + math.sqrt(vy**2 + 2 * G * h)) / G
    _friction_bundle(tmp_path, _roller(0.5, mu, e).system, [0.0, R + h, 0.0, vx, -vy, 0.0], 1.0, outputs=["energy"])
    t_end = t_hit + 1e-3
    proc = _run(["./rk4_example", "-t", repr(t_end), "-n", "1000", "-e", "1000"], tmp_path)
    events = _friction_events(proc.stderr)
    assert [ev[2] for ev in events] == ["bounce", "tangential impulse"], proc.stderr
    bounce, tang = events
    v_hit = vy + G * t_hit
    pn = (1 + e) * v_hit
    assert bounce[0] == pytest.approx(t_hit, rel=1e-10) and bounce[3] == pytest.approx(pn, rel=1e-10)
    if sticks:
        assert abs(vx / 3) <= mu * pn
        assert tang[3] == pytest.approx(-vx / 3, rel=1e-10) and abs(tang[5]) < 1e-12
        vx_after, w_after = 2 * vx / 3, -2 * vx / (3 * R)
    else:
        assert abs(vx / 3) > mu * pn
        assert tang[3] == pytest.approx(-mu * pn, rel=1e-10)
        vx_after, w_after = vx - mu * pn, -2 * mu * pn / R
        assert tang[5] == pytest.approx(vx_after + R * w_after, rel=1e-10) and tang[5] > 0
    names, rows = _table(proc.stdout)
    assert rows[-1, names.index("x_dot")] == pytest.approx(vx_after, rel=1e-10)
    assert rows[-1, names.index("phi_dot")] == pytest.approx(w_after, rel=1e-10)


@pytest.mark.parametrize("mu", [0.2, 0.8])
def test_particle_launched_across_a_3d_incline_bundle_curves_as_an_independent_integration(tmp_path, tools, mu):
    """3-D friction (two tangents turned by 0.3 rad, the circular cone): the particle launched
    across an incline (alpha = 0.5) against scipy's DOP853 on the closed form x'' = g sin(alpha) -
    mu N u_x / |u|, y'' = -mu N u_y / |u| to 1e-8 (positions); with mu = 0.8 > tan(alpha) it stops
    (one grip) and stays; make check against the impact driver. The stop's time: near it the
    slip direction's rate mu N / (m |u|) exceeds RK4's stability bound at a fixed step h once
    |u| < ~h mu g, so the example's last steps before it are inaccurate across the slip (harmless
    to the positions, the speed being small): to 2e-5 at the default h = 1e-3 (measured 1.2e-5),
    to 1e-9 at h = 1e-4 (the closed form's stop: DOP853's event at |u| = 1e-9 plus 1e-9 over the
    deceleration g (mu cos(alpha) - sin(alpha)) of the straight final approach)."""
    from scipy.integrate import solve_ivp
    from test_friction_speeds import _incline_3d
    alpha, vy0 = 0.5, 3.0
    n = G * math.cos(alpha)

    def f(t, s):
        speed = math.hypot(s[2], s[3])
        return [s[2], s[3], G * math.sin(alpha) - mu * n * s[2] / speed, -mu * n * s[3] / speed]

    def stops(t, s):
        return math.hypot(s[2], s[3]) - 1e-9
    stops.terminal = True
    ref = solve_ivp(f, (0, 3.0), [0, 0, 0, vy0], method="DOP853", rtol=1e-13, atol=1e-14, events=stops,
                    dense_output=True)
    files = _friction_bundle(tmp_path, _incline_3d(alpha, mu, 0.3).system, [0, 0, 0, 0, vy0, 0], 3.0,
                             outputs=["energy"])
    assert "lambda_t1_ineq_0" in files["reference.csv"] and "#define NROW 3" in files["rk4_example.c"]
    proc = _run(["./rk4_example", "-e", "10"], tmp_path)
    names, rows = _table(proc.stdout)
    assert names[1:7] == ["x", "y", "z", "x_dot", "y_dot", "z_dot"] and names[-2:] == ["lambda_t0_ineq_0",
                                                                                        "lambda_t1_ineq_0"]
    stopped = ref.t[-1] if mu > math.tan(alpha) else 3.0
    moving = rows[:, 0] <= stopped
    assert np.abs(rows[moving, 1:3] - ref.sol(rows[moving, 0])[:2].T).max() < 1e-8
    assert np.max(np.abs(rows[:, 3])) < 1e-12  # z: on the incline
    grips = [ev for ev in _friction_events(proc.stderr) if ev[2] == "grip"]
    if mu > math.tan(alpha):
        t_stop = ref.t_events[0][0] + 1e-9 / (G * (mu * math.cos(alpha) - math.sin(alpha)))
        assert len(grips) == 1 and grips[0][0] == pytest.approx(t_stop, rel=2e-5)
        fine = [ev for ev in _friction_events(_run(["./rk4_example", "-n", "30000", "-e", "30000"], tmp_path).stderr)
                if ev[2] == "grip"]
        assert len(fine) == 1 and fine[0][0] == pytest.approx(t_stop, rel=1e-9)
        assert np.abs(rows[~moving, 4:6]).max() < 1e-12
        assert np.abs(rows[~moving, 1:3] - ref.y[:2, -1]).max() < 1e-8
        assert _final_modes(proc.stderr) == {0: "stick"}
    else:
        assert grips == [] and _final_modes(proc.stderr) == {0: "slip"}


def test_ladder_bundle_stays_when_mu_reaches_one_over_two_tan_alpha_and_slips_below(tmp_path, tools):
    """Two contacts, one frictionless (the wall), one with Coulomb friction (the floor): the ladder
    leaning at alpha = 0.9 stays when mu >= 1 / (2 tan(alpha)) (the wall's push and the floor's
    friction m g / (2 tan(alpha)), N = m g, to 1e-9; the foot and the angle unmoved to 1e-12) and
    slips below (the foot moves out, the ladder falls); make check against the impact driver. mu is
    a literal of the example, so each case is its own bundle."""
    from test_friction import _ladder
    alpha, L = 0.9, 2.0
    mu_c = 1 / (2 * math.tan(alpha))
    y0 = [L / 2 * math.cos(alpha), L / 2 * math.sin(alpha), alpha, 0.0, 0.0, 0.0]
    for mu, stays in ((mu_c + 1e-6, True), (mu_c - 1e-6, False)):
        folder = tmp_path / ("stays" if stays else "slips")
        _friction_bundle(folder, _ladder(alpha, mu, L)[0].system, y0, 0.5)
        proc = _run(["./rk4_example", "-e", "50"], folder)
        names, rows = _table(proc.stdout)
        col = {name: i for i, name in enumerate(names)}
        foot = rows[:, col["x"]] + L / 2 * np.cos(rows[:, col["theta"]])
        if stays:
            assert _final_modes(proc.stderr) == {0: "contact", 1: "stick"}
            assert np.max(np.abs(foot - foot[0])) < 1e-12 and np.max(np.abs(rows[:, col["theta"]] - alpha)) < 1e-12
            assert rows[-1, col["lambda_ineq_0"]] == pytest.approx(G * mu_c, rel=1e-9)
            assert rows[-1, col["lambda_t_ineq_1"]] == pytest.approx(-G * mu_c, rel=1e-9)
            assert rows[-1, col["lambda_ineq_1"]] == pytest.approx(G, rel=1e-9)
        else:
            assert _final_modes(proc.stderr)[1] == "slip+"
            assert foot[-1] > foot[0] + 1e-9 and rows[-1, col["theta"]] < alpha


@pytest.mark.parametrize("alpha, mu", [(0.3, 0.4), (0.3, 0.2)])
def test_box_on_two_rough_corners_bundle_sticks_or_slides_as_one_contact(tmp_path, tools, alpha, mu):
    """Two Coulomb contacts solved together by the core (sticking on both: four rows holding three
    motions, dependent): the box stays while tan(alpha) <= mu, else slides at g (sin(alpha) -
    mu cos(alpha)) without tipping (x to 1e-9 relative, phi below 1e-10), the normal forces adding
    up to m g cos(alpha) (1e-8)."""
    from test_friction import _box_on_incline
    sim, q0 = _box_on_incline(alpha, mu)
    _friction_bundle(tmp_path, sim.system, [*q0, 0.0, 0.0, 0.0], 1.0)
    proc = _run(["./rk4_example", "-e", "100"], tmp_path)
    names, rows = _table(proc.stdout)
    col = {name: i for i, name in enumerate(names)}
    t, x = rows[:, 0], rows[:, col["x"]]
    total = rows[:, col["lambda_ineq_0"]] + rows[:, col["lambda_ineq_1"]]
    assert np.max(np.abs(total / (G * math.cos(alpha)) - 1)) < 1e-8
    assert np.max(np.abs(rows[:, col["phi"]])) < 1e-10
    if math.tan(alpha) <= mu:
        assert _final_modes(proc.stderr) == {0: "stick", 1: "stick"} and np.max(np.abs(x)) < 1e-12
    else:
        assert _final_modes(proc.stderr) == {0: "slip+", 1: "slip+"}
        acc = G * (math.sin(alpha) - mu * math.cos(alpha))
        assert np.max(np.abs(x[1:] / (0.5 * acc * t[1:] ** 2) - 1)) < 1e-9


def test_painleve_rod_bundle_reports_the_paradox_by_name_and_exit_status(tmp_path, tools):
    """Painleve's rod (mu = 2, its end on the rough floor): at tan(theta) = 2 sliding to -x no mode
    is consistent (the example stops at its start with exit status 3 and the core's message); from
    30 degrees sliding fast to -x it turns up until the contact problem becomes singular, where
    G M^-1 (G + mu T)^T = 1 + 3 cos^2 - 6 sin cos = 0, tan(theta) = 3 - sqrt(5): the example
    stops there (exit status 3, the message with the time), never integrating on."""
    from test_friction import _painleve_rod
    theta0 = math.atan(2.0)
    _friction_bundle(tmp_path, _painleve_rod(2.0, theta0)[0].system, [math.cos(theta0), math.sin(theta0), theta0, -1.0, 0.0, 0.0],
                     0.3, reference=False)
    proc = _run(["./rk4_example"], tmp_path, check=False)
    assert proc.returncode == 3, proc.stderr
    assert "initial state: Painleve's paradox (inconsistency) at t = 0" in proc.stderr and proc.stdout == ""
    theta0 = math.radians(30)
    proc = _run(["./rk4_example", "-e", "1", repr(math.cos(theta0)), repr(math.sin(theta0)), repr(theta0), "-20", "0",
                 "0"], tmp_path, check=False)
    assert proc.returncode == 3, proc.stderr
    m = re.search(r"Painleve's paradox at t = (\S+): the contact problem of the slipping contact\(s\) became singular",
                  proc.stderr)
    assert m, proc.stderr
    t_stop = float(m.group(1))
    names, rows = _table(proc.stdout)
    assert 0 < t_stop < 0.3 and rows[-1, 0] < t_stop <= rows[-1, 0] + 0.3 / 1000
    theta = rows[:, names.index("theta")]
    assert np.all(np.tan(theta) < 3 - math.sqrt(5)) and math.tan(theta[-1]) > 0.99 * (3 - math.sqrt(5))


def test_command_line_bundle_of_a_model_file_with_friction(tmp_path, tools):
    """`lagcodegen generate --bundle` on the model file of tests/test_friction.py (a block sent
    along a rough floor at 3 m/s, mu = 0.25): make check passes and the example's block stops at
    v0 / (mu g), x = v0^2 / (2 mu g), and sticks."""
    import sys
    from test_friction import SLIDER_FILE
    (tmp_path / "slider.toml").write_text(SLIDER_FILE)
    out = tmp_path / "bundle"
    _run([sys.executable, "-m", "lagcodegen", "generate", "slider.toml", "-o", str(out), "--bundle", "-q"], tmp_path)
    assert "rk4_example agrees with reference.csv" in _run(["make", f"CFLAGS={STRICT}", "check"], out).stdout
    proc = _run(["./rk4_example", "-e", "2000"], out)
    t_stop = 3.0 / (0.25 * G)
    assert [(ev[2], ev[0]) for ev in _friction_events(proc.stderr)] == [("grip", pytest.approx(t_stop, rel=1e-12))]
    names, rows = _table(proc.stdout)
    assert rows[-1, names.index("x")] == pytest.approx(3.0 * t_stop / 2, rel=1e-12)
    assert _final_modes(proc.stderr) == {0: "stick"}


def test_friction_bundle_ships_the_runtime_friction_core_as_it_is():
    """The friction law of the example is the runtime's lcg_imp_fric.c (the file the impact
    drivers use), shipped unchanged and compiled into the library, not a copy in the example."""
    from lagcodegen.runtime import source
    from test_friction import _incline
    files = render_constrained_bundle(_incline(0.5, 0.3).system, outputs=["energy"], reference=False)
    for name in ("lcg_imp_fric.c", "lcg_imp_fric.h", "lcg_imp_law.c", "lcg_imp_law.h"):
        assert files[name] == source(name)
    example = files["rk4_example.c"]
    for call in ("lcg_fr_crhs(&fc", "lcg_fr_modes(&fc", "lcg_fr_impact(&fc", "lcg_fr_setup(&fr"):
        assert call in example
    assert "fr_solve" not in example and "fr_lu" not in example  # the contact problem is the core's
    assert "lcg_imp_fric.o" in files["Makefile"] and "lcg_imp_fric.c" in files["CMakeLists.txt"]
    assert "lcg_imp_fric.c" in files["README.md"]
    frictionless = render_constrained_bundle(_ball_system(), outputs=["energy"], reference=False)
    assert "lcg_imp_fric.c" not in frictionless and "lcg_imp_fric" not in frictionless["Makefile"]


def test_friction_bundle_clean_under_sanitizers(tmp_path, tools):
    """The friction example under AddressSanitizer and UBSan, leaks detected: a disc bouncing on
    the rough floor (frictional impacts, slip, grip, rolling), the particle launched across the
    3-D incline (the cone: slip, its direction renewed, grip), Painleve's rod (exit status 3, the
    core's memory freed); bad command lines and a violated start (exit status 2 and 1)."""
    import os
    from test_friction import _painleve_rod, _roller
    from test_friction_speeds import _incline_3d
    flags = "-fsanitize=address,undefined -fno-sanitize-recover=all"
    env = {**os.environ, "ASAN_OPTIONS": "detect_leaks=1", "UBSAN_OPTIONS": "print_stacktrace=1"}

    def build(name, system, y0, t_end):
        folder = tmp_path / name
        write_files(folder, render_constrained_bundle(system, reference=False, y0=y0, t_end=t_end))
        _run(["make", f"CFLAGS=-O1 -g -std=c99 {flags}", f"LDFLAGS={flags}", "rk4_example"], folder)
        return folder

    def sanitized(folder, args, status=0):
        proc = subprocess.run(["./rk4_example", *args], cwd=folder, capture_output=True, text=True, env=env,
                              timeout=300)
        assert proc.returncode == status, proc.stderr
        assert "runtime error" not in proc.stderr and "Sanitizer" not in proc.stderr, proc.stderr
        return proc

    disc = build("disc", _roller(0.5, 0.1, 0.5).system, [0.0, 0.4, 0.0, 4.0, -2.0, 3.0], 2.0)
    kinds = [ev[2] for ev in _friction_events(sanitized(disc, ["-e", "100"]).stderr)]
    assert "bounce" in kinds and "tangential impulse" in kinds and "grip" in kinds
    for bad in (["-n", "0"], ["-p", "nope=1"], ["1.0"]):
        sanitized(disc, bad, 2)
    assert "violated at the start" in sanitized(disc, ["0", "0.2", "0", "0", "0", "0"], 1).stderr
    across = build("across", _incline_3d(0.5, 0.8, 0.3).system, [0, 0, 0, 0, 3.0, 0], 1.0)
    assert [ev[2] for ev in _friction_events(sanitized(across, ["-e", "100"]).stderr)] == ["grip"]
    theta0 = math.radians(30)
    rod = build("rod", _painleve_rod(2.0, theta0)[0].system, [math.cos(theta0), math.sin(theta0), theta0, -20.0, 0.0, 0.0], 0.3)
    assert "Painleve's paradox at t = " in sanitized(rod, ["-e", "100"], 3).stderr
