"""Bundles of constrained systems (index-1 formulation, C and Fortran): make and CMake builds with
only gcc/gfortran, the RK4 example against lagcodegen's own CVODE integration (plain, Baumgarte,
projection), sanitizers, byte-stable regeneration."""

import csv
import os
import subprocess

import numpy as np
import pytest

from lagcodegen import ModelError, write_bundle
from lagcodegen.codegen.bundle import render_constrained_bundle
from lagcodegen.api import compile_constrained
from lagcodegen.model.events import Event

from helpers import cartesian_pendulum, knife_edge, pendulum_q0

T_END = 10.0
Y0 = [float(v) for v in pendulum_q0()] + [0.0, 0.0]
OUTPUTS = ["energy", "lambda", "residuals"]
BAUMGARTE = (5.0, 5.0)


@pytest.fixture(scope="module")
def pendulum():
    return cartesian_pendulum("bpend")


@pytest.fixture(scope="module")
def references(pendulum):
    """lagcodegen's index-1 result at T_END (native CVODE, rtol 1e-10), plain and with Baumgarte
    stabilization, and with parameter l = 1.5 (the initial state projected onto the constraint)."""
    sim = compile_constrained(pendulum, "index1", outputs=OUTPUTS)
    kw = dict(q0=Y0[:2], v0=Y0[2:], rtol=1e-10, atol=1e-12)
    return {"plain": sim.simulate([0.0, T_END], **kw).y[-1],
            "baumgarte": sim.simulate([0.0, T_END], baumgarte=BAUMGARTE, **kw).y[-1],
            "long": sim.simulate([0.0, T_END], initial="project", params={"l": 1.5}, **kw).y[-1]}


def run(cmd, cwd, env=None, check=True):
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, env=env, timeout=300)
    if check:
        assert proc.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{proc.stdout}\n{proc.stderr}"
    return proc


def rows(text):
    table = list(csv.reader(text.splitlines()))
    return table[0], np.array([[float(v) for v in row] for row in table[1:]])


@pytest.mark.parametrize("lang", ["c", "fortran"])
def test_constrained_bundle_builds_and_matches_cvode(tmp_path, tools, pendulum, references, lang):
    paths = write_bundle(pendulum, tmp_path, lang=lang, y0=Y0, t_end=T_END, outputs=OUTPUTS)
    source = f"bpend_dae.{'f90' if lang == 'fortran' else 'c'}"
    assert sorted(p.name for p in paths) == sorted(["CMakeLists.txt", "Makefile", "README.md", "rk4_example.c",
                                                   "bpend_dae.h", source, "reference.csv"])
    readme = (tmp_path / "README.md").read_text()
    for fn in ("kkt", "crhs", "residuals", "project", "coutputs"):
        assert f"bpend_{fn}" in readme
    assert "BPEND_DAE_ERR_PROJECTION" in readme and "Baumgarte" in readme

    # make: `make check` runs the example with the defaults baked into the bundle.
    run(["make"], tmp_path)
    assert (tmp_path / "libbpend.a").is_file()
    check = run(["make", "check"], tmp_path)
    assert "make check: rk4_example agrees with reference.csv at t = 1: " in check.stdout
    header, table = rows((tmp_path / "rk4_example.csv").read_text())
    assert header == ["t", "x", "y", "x_dot", "y_dot", "energy", "lambda_0", "g_0", "gdot_0"]
    final = table[-1]
    assert final[0] == T_END and table.shape[0] == 101
    np.testing.assert_allclose(final[1:5], references["plain"], rtol=0, atol=1e-6)
    assert abs(final[7]) < 1e-7 and np.ptp(table[:, 5]) < 1e-7  # f(q) and energy: drift only
    # The rod tension -2 l lambda (l = m = 1) is m (g cos(theta) + l theta'^2) = g (-y) + |v|^2.
    tension = 9.81 * -table[:, 2] + table[:, 3] ** 2 + table[:, 4] ** 2
    np.testing.assert_allclose(-2.0 * table[:, 6], tension, rtol=0, atol=1e-8 * np.max(tension))

    # CMake, out of source; Baumgarte parameters, per-step projection and a parameter on the command line.
    run(["cmake", "-S", ".", "-B", "build"], tmp_path)
    run(["cmake", "--build", "build"], tmp_path)
    assert (tmp_path / "build" / "libbpend.a").is_file()
    exe = str(tmp_path / "build" / "rk4_example")
    _, table = rows(run([exe, "-a", "5", "-b", "5", "-e", "10000"], tmp_path).stdout)
    assert table.shape[0] == 2
    np.testing.assert_allclose(table[-1, 1:5], references["baumgarte"], rtol=0, atol=1e-6)
    _, table = rows(run([exe, "-P", "-e", "1000"], tmp_path).stdout)
    np.testing.assert_allclose(table[-1, 1:5], references["plain"], rtol=0, atol=1e-6)
    assert np.max(np.abs(table[:, 7:9])) < 1e-12  # projected after every step
    _, table = rows(run([exe, "-p", "l=1.5", "-n", "10000", "-e", "10000", *map(repr, Y0)], tmp_path).stdout)
    assert abs(np.hypot(table[0, 1], table[0, 2]) - 1.5) < 1e-14  # initial state projected
    np.testing.assert_allclose(table[-1, 1:5], references["long"], rtol=0, atol=1e-6)

    # A bad command line is refused with exit status 2.
    for bad in (["-n"], ["-a", "x"], ["1.0"], ["-t", "-1"]):
        proc = run([exe, *bad], tmp_path, check=False)
        assert proc.returncode == 2 and "usage" in proc.stderr, bad


def test_constrained_c_bundle_clean_under_sanitizers(tmp_path, tools, pendulum, references):
    write_bundle(pendulum, tmp_path, lang="c", y0=Y0, t_end=T_END, outputs=OUTPUTS)
    flags = "-fsanitize=address,undefined -fno-sanitize-recover=all"
    run(["make", f"CFLAGS=-O1 -g -std=c99 {flags}", f"LDFLAGS={flags}", "rk4"], tmp_path)
    env = {**os.environ, "ASAN_OPTIONS": "detect_leaks=1", "UBSAN_OPTIONS": "print_stacktrace=1"}
    for args, ref in ((["-e", "1000"], "plain"), (["-P", "-a", "5", "-b", "5", "-e", "1000"], "baumgarte")):
        proc = run(["./rk4_example", *args], tmp_path, env=env)
        assert "runtime error" not in proc.stderr and "AddressSanitizer" not in proc.stderr
        _, table = rows(proc.stdout)
        np.testing.assert_allclose(table[-1, 1:5], references[ref], rtol=0, atol=1e-6)
    for bad in (["-n", "0"], ["-p", "nope=1"], ["-p", "g"], ["1.0", "2.0"], ["x"], ["-b"]):
        proc = run(["./rk4_example", *bad], tmp_path, env=env, check=False)
        assert proc.returncode == 2, (bad, proc.stderr)
        assert "runtime error" not in proc.stderr and "AddressSanitizer" not in proc.stderr
    # An initial state that cannot be projected (the origin: A = 0) fails with exit status 1.
    proc = run(["./rk4_example", "0", "0", "0", "0"], tmp_path, env=env, check=False)
    assert proc.returncode == 1 and "initial state" in proc.stderr and "runtime error" not in proc.stderr


@pytest.mark.parametrize("lang", ["c", "fortran"])
def test_constrained_regeneration_changes_no_byte_and_no_mtime(tmp_path, tools, pendulum, lang):
    first = render_constrained_bundle(pendulum, lang, outputs=OUTPUTS)
    assert render_constrained_bundle(pendulum, lang, outputs=OUTPUTS) == first
    paths = write_bundle(pendulum, tmp_path, lang=lang, outputs=OUTPUTS)
    run(["make"], tmp_path)
    before = {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in paths}
    again = write_bundle(pendulum, tmp_path, lang=lang, outputs=OUTPUTS)
    assert {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in again} == before
    assert run(["make", "-q"], tmp_path, check=False).returncode == 0  # nothing to rebuild
    assert not any("\r" in text for text in first.values())


def test_nonholonomic_fortran_bundle_with_ggl_functions_and_events(tmp_path, tools):
    """The knife edge (no holonomic constraint), every parameter folded, the GGL functions and an
    event function included; the example compiles with strict warnings and matches CVODE."""
    cs = knife_edge("bknife")
    y0 = [0.0, 0.0, 0.0, 0.0, 0.0, 1.5]
    write_bundle(cs, tmp_path, lang="fortran", y0=y0, t_end=5.0, steps=5000, ggl=True, runtime_parameters=[],
                 events=[Event("lam", cs.multipliers[0], 0, False)], outputs=["energy", "residuals"])
    src = (tmp_path / "bknife_dae.f90").read_text()
    assert 'name="bknife_ggl_jac"' in src and 'name="bknife_roots"' in src
    readme = (tmp_path / "README.md").read_text()
    assert "bknife_ggl_res" in readme and "nonholonomic" in readme and "None: every parameter is folded" in readme
    run(["gcc", "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic", "-c", "rk4_example.c"], tmp_path)
    run(["make", "check"], tmp_path)
    _, table = rows((tmp_path / "rk4_example.csv").read_text())
    ref = compile_constrained(cs, "index1", outputs=["energy"]).simulate(
        [0.0, 5.0], q0=y0[:3], v0=y0[3:], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(table[-1, 1:7], ref.y[-1], rtol=0, atol=1e-6)
    assert np.max(np.abs(table[:, 8])) < 1e-9 and np.ptp(table[:, 7]) < 1e-9  # A q' and energy


@pytest.mark.parametrize("lang", ["c", "fortran"])
def test_bundle_of_a_pinned_quaternion_body(tmp_path, tools, lang):
    """Generalized speeds in a bundle: a body on a free joint (quaternion, speeds in its frame)
    pinned at a body point (3 holonomic rows); state (q[7], v[6]); `make check` passes and the
    RK4 example's final state matches lagcodegen's CVODE run to 1e-8, the quaternion of unit norm."""
    import lagcodegen as lcg
    from lagcodegen.theory.constraints import ConstrainedSystem
    m = lcg.Model("bpinned")
    m.link("body", joint=lcg.Joint.free("root"), mass=1.0, inertia=(0.1, 0.2, 0.3, 0, 0, 0))
    m.gravity(9.81)
    rb, w = np.array([0.1, 0.2, 0.5]), np.array([0.7, -1.1, 2.3])
    cs = ConstrainedSystem(m, holonomic=list(m.point_on("body", tuple(rb), "pivot").position))
    y0 = [float(x) for x in np.concatenate([-rb, [0, 0, 0, 1], -np.cross(w, rb), w])]
    write_bundle(cs, tmp_path, lang=lang, y0=y0, t_end=2.0, steps=4000, outputs=["energy", "residuals"])
    readme = (tmp_path / "README.md").read_text()
    assert "the next 6 the generalized speeds v" in readme and "ydot[13]" in readme
    run(["gcc", "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic", "-c", "rk4_example.c"], tmp_path)
    check = run(["make", "check"], tmp_path)
    assert "make check: rk4_example agrees with reference.csv at t = 1: 21 values" in check.stdout
    header, table = rows((tmp_path / "rk4_example.csv").read_text())
    assert header[1:14] == [q.name for q in m.coords] + [v.name for v in m.v]
    ref = compile_constrained(cs, "index1").simulate([0.0, 2.0], q0=y0[:7], v0=y0[7:], rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(table[-1, 1:14], ref.y[-1], rtol=0, atol=1e-8)
    assert abs(np.linalg.norm(table[-1, 4:8]) - 1) < 1e-12 and np.abs(table[:, 15:18]).max() < 1e-8


def test_bad_constrained_bundle_options_write_nothing(tmp_path, pendulum):
    target = tmp_path / "out"
    for kwargs in (dict(lang="cobol"), dict(y0=[1.0, 2.0, 3.0]), dict(params={"nope": 1.0}), dict(t_end=-1.0),
                   dict(steps=0), dict(baumgarte=(float("nan"), 0.0)), dict(sundials_example=True),
                   dict(outputs=["tension"])):
        with pytest.raises(ModelError):
            write_bundle(pendulum, target, **kwargs)
        assert not target.exists()
    with pytest.raises(ModelError, match="ConstrainedSystem"):
        render_constrained_bundle(pendulum.model)


def test_the_example_defaults_as_a_record_or_as_keywords(pendulum):
    from lagcodegen.codegen.bundle import ExampleRun
    keywords = render_constrained_bundle(pendulum, outputs=OUTPUTS, y0=[0.3, 0.0, 0.0, 0.0], t_end=2.0, steps=400,
                                         reference=False)
    record = render_constrained_bundle(pendulum, outputs=OUTPUTS, reference=False,
                                       example=ExampleRun(y0=[0.3, 0.0, 0.0, 0.0], t_end=2.0, steps=400))
    assert record == keywords
    assert keywords["rk4_example.c"] != render_constrained_bundle(pendulum, outputs=OUTPUTS, reference=False)[
        "rk4_example.c"]
    with pytest.raises(TypeError, match="unexpected keyword argument 't_final'"):
        render_constrained_bundle(pendulum, t_final=2.0)
    with pytest.raises(TypeError, match="not both"):
        render_constrained_bundle(pendulum, example=ExampleRun(), t_end=2.0)
