"""Bundles of constrained systems with contacts: the contact functions and their impact law in the
bundle's C, driven by its RK4 example (impacts located by bisection within a step, persistent
contact, release), built with make (strict flags, `make check` against reference.csv) and CMake,
checked against the closed-form bouncing ball and Newton's cradle (the facts tests/test_impacts.py
checks the impact driver with)."""

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


def test_contact_bundles_refuse_what_they_do_not_carry():
    with pytest.raises(ModelError, match="contacts are made in C only"):
        render_constrained_bundle(_ball_system(), "fortran", outputs=["energy"], reference=False)
    with pytest.raises(ModelError, match="Coulomb friction"):
        render_constrained_bundle(_ball_system(friction=0.5), outputs=["energy"], reference=False)


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
