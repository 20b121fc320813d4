"""Embeddable bundles: make and CMake builds with only gcc/gfortran, the RK4 example against
lagcodegen's own CVODE integration, sanitizers, byte-stable regeneration, generate --check."""

import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen import ModelError, Scene, derive, generate_c, render_bundle, systems, write_bundle

ROOT = Path(__file__).resolve().parents[2]

# Two systems: the double pendulum (nonlinear, run-time and folded parameters) and the damped
# driven oscillator (time-dependent forcing: RK4 must evaluate f at t + h/2 and t + h).
SETUPS = {
    "double_pendulum": dict(model=systems.double_pendulum,
                            scene=dict(outputs=["energy"], runtime_parameters=["g", "m1"], values={"l2": 0.7}),
                            y0=[1.0, 0.5, 0.0, 0.0], params={"m1": 1.5}, t_end=10.0, other={"g": 9.0}),
    "oscillator": dict(model=systems.damped_driven_oscillator, scene=dict(outputs=["energy"]),
                       y0=[1.0, 0.0], params={"w": 1.3}, t_end=10.0, other={"w": 1.7}),
}
CASES = [(name, lang) for name in SETUPS for lang in ("c", "fortran")]


@pytest.fixture(scope="module")
def scenes():
    return {name: Scene(derive(s["model"]()), **s["scene"]) for name, s in SETUPS.items()}


@pytest.fixture(scope="module")
def references(scenes):
    """lagcodegen's native CVODE result at t_end (rtol 1e-10), with the bundle's default
    parameters and with the `other` ones, per system."""
    refs = {}
    for name, scene in scenes.items():
        s = SETUPS[name]
        cm = lcg.build_code(generate_c(scene))
        for key, params in (("default", s["params"]), ("other", {**s["params"], **s["other"]})):
            res = cm.simulate([0.0, s["t_end"]], y0=s["y0"], params=params, rtol=1e-10, atol=1e-12)
            refs[name, key] = res.y[-1]
    return refs


def cm_reference(scene, setup, t_end):
    """The state at ``t_end`` by lagcodegen's CVODE from the setup's y0 and parameters (rtol 1e-12)."""
    cm = lcg.build_code(generate_c(scene))
    return cm.simulate([0.0, t_end], y0=setup["y0"], params=setup["params"], rtol=1e-12, atol=1e-14).y[-1]


def run(cmd, cwd, env=None, check=True):
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, env=env, timeout=300)
    if check:
        assert proc.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{proc.stdout}\n{proc.stderr}"
    return proc


def last_row(text):
    rows = list(csv.reader(text.splitlines()))
    return rows[0], np.array([float(v) for v in rows[-1]])


@pytest.mark.parametrize("name,lang", CASES)
def test_bundle_builds_with_make_and_cmake_and_matches_cvode(tmp_path, tools, scenes, references, name, lang):
    s = SETUPS[name]
    scene = scenes[name]
    paths = write_bundle(scene, tmp_path, lang=lang, y0=s["y0"], params=s["params"], t_end=s["t_end"])
    source = f"{scene.prefix}.{'f90' if lang == 'fortran' else 'c'}"
    taylor = [f"{scene.prefix}_taylor.c", f"{scene.prefix}_taylor.h", "taylor_example.c"] if lang == "c" else []
    assert sorted(p.name for p in paths) == sorted(["CMakeLists.txt", "Makefile", "README.md", "cvode_example.c",
                                                   "rk4_example.c", f"{scene.prefix}.h", source, *taylor,
                                                   "reference.csv"])
    ny = len(s["y0"])

    # make: library, example, `make check` runs it with the defaults baked into the bundle.
    run(["make"], tmp_path)
    assert (tmp_path / f"lib{scene.prefix}.a").is_file()
    check = run(["make", "check"], tmp_path)
    header, final = last_row((tmp_path / "rk4_example.csv").read_text())
    model = scene.eom.model
    assert header == ["t", *(q.name for q in model.coords), *(v.name for v in model.speeds), "energy"]
    assert final[0] == s["t_end"]
    np.testing.assert_allclose(final[1:ny + 1], references[name, "default"], rtol=0, atol=1e-6)
    # make check compares a short run with reference.csv (lagcodegen's CVODE, written with the bundle)
    assert "make check: rk4_example agrees with reference.csv at t = 1: " in check.stdout
    reference = (tmp_path / "reference.csv").read_text()
    ref_header, ref_row = last_row("\n".join(ln for ln in reference.splitlines() if not ln.startswith("#")))
    assert ref_header == header and ref_row[0] == 1.0
    short = cm_reference(scene, s, 1.0)
    np.testing.assert_allclose(ref_row[1:ny + 1], short, rtol=0, atol=1e-10)
    lines = reference.splitlines()
    values = lines[-1].split(",")
    values[2] = repr(float(values[2]) + 1e-3)  # the second state off by 1e-3: make check fails naming it
    (tmp_path / "reference.csv").write_text("\n".join(lines[:-1] + [",".join(values)]) + "\n")
    failed = run(["make", "check"], tmp_path, check=False)
    assert failed.returncode != 0, failed.stdout
    assert f"make check: {header[2]} = " in failed.stdout and "1e-06 (1 + |reference|)" in failed.stdout
    (tmp_path / "reference.csv").write_text(reference)
    if lang == "c":  # the Taylor example, built and run by `make check` with only a compiler
        taylor_header, final_taylor = last_row((tmp_path / "taylor_example.csv").read_text())  # a CSV
        assert taylor_header == header
        assert "taylor_example: final row" in check.stdout and "flag 0: " in check.stderr  # the status on stderr
        assert final_taylor[0] == pytest.approx(s["t_end"])
        np.testing.assert_allclose(final_taylor[1:ny + 1], references[name, "default"], rtol=0, atol=1e-6)

    # CMake, out of source; the same example with parameters and the initial state on the command line.
    run(["cmake", "-S", ".", "-B", "build"], tmp_path)
    run(["cmake", "--build", "build"], tmp_path)
    assert (tmp_path / "build" / f"lib{scene.prefix}.a").is_file()
    args = []
    for key, value in s["other"].items():
        args += ["-p", f"{key}={value!r}"]
    args += ["-t", repr(s["t_end"]), "-n", "20000", "-e", "20000", *map(repr, s["y0"])]
    proc = run([str(tmp_path / "build" / "rk4_example"), *args], tmp_path)
    _, final = last_row(proc.stdout)
    np.testing.assert_allclose(final[1:ny + 1], references[name, "other"], rtol=0, atol=1e-6)
    assert len(proc.stdout.splitlines()) == 3  # header, t0, t_end

    # A bad command line is refused with exit status 2.
    bad = run([str(tmp_path / "build" / "rk4_example"), "-n"], tmp_path, check=False)
    assert bad.returncode == 2 and "usage" in bad.stderr


def test_c_bundle_clean_under_sanitizers(tmp_path, tools, scenes, references):
    s = SETUPS["double_pendulum"]
    write_bundle(scenes["double_pendulum"], tmp_path, lang="c", y0=s["y0"], params=s["params"], t_end=s["t_end"])
    flags = "-fsanitize=address,undefined -fno-sanitize-recover=all"
    run(["make", f"CFLAGS=-O1 -g -std=c99 {flags}", f"LDFLAGS={flags}", "rk4"], tmp_path)
    env = {**os.environ, "ASAN_OPTIONS": "detect_leaks=1", "UBSAN_OPTIONS": "print_stacktrace=1"}
    proc = run(["./rk4_example", "-e", "1000"], tmp_path, env=env)
    assert "runtime error" not in proc.stderr and "AddressSanitizer" not in proc.stderr
    _, final = last_row(proc.stdout)
    np.testing.assert_allclose(final[1:5], references["double_pendulum", "default"], rtol=0, atol=1e-6)
    for bad in (["-n", "0"], ["-p", "nope=1"], ["-p", "g"], ["1.0", "2.0"], ["x"], ["-t", "-1"]):
        proc = run(["./rk4_example", *bad], tmp_path, env=env, check=False)
        assert proc.returncode == 2, (bad, proc.stderr)
        assert "runtime error" not in proc.stderr and "AddressSanitizer" not in proc.stderr


@pytest.mark.parametrize("lang", ["c", "fortran"])
def test_regeneration_changes_no_byte_and_no_mtime(tmp_path, tools, scenes, lang):
    scene = scenes["oscillator"]
    first = render_bundle(scene, lang)
    assert render_bundle(scene, lang) == first
    paths = write_bundle(scene, tmp_path, lang=lang)
    run(["make"], tmp_path)
    before = {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in paths}
    again = write_bundle(scene, tmp_path, lang=lang)
    assert {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in again} == before
    assert run(["make", "-q"], tmp_path, check=False).returncode == 0  # nothing to rebuild
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]
    assert not any("\r" in text for text in first.values())


def test_rk4_example_strict_without_parameters_or_outputs(tmp_path, tools):
    scene = Scene(derive(systems.pendulum("bare")), runtime_parameters=[], jacobian=False)
    write_bundle(scene, tmp_path, lang="c", sundials_example=False, t_end=1.0, steps=100)
    assert not (tmp_path / "cvode_example.c").exists()
    assert "cvode" not in (tmp_path / "CMakeLists.txt").read_text().lower()
    strict = ["gcc", "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic"]
    run([*strict, "rk4_example.c", "bare.c", "-o", "rk4", "-lm"], tmp_path)
    header, final = last_row(run(["./rk4"], tmp_path).stdout)
    assert header == ["t", "theta", scene.eom.model.speeds[0].name] and final[0] == 1.0


def test_cvode_example_compiles_against_sundials_headers(tmp_path, scenes):
    include = sundials_include()
    if include is None:
        pytest.skip("no SUNDIALS headers (cvode/cvode.h) installed")
    write_bundle(scenes["double_pendulum"], tmp_path, lang="c")
    run(["gcc", "-Wall", "-Wextra", "-Werror", "-std=c99", f"-I{include}/include", "-fsyntax-only",
         "cvode_example.c"], tmp_path)


def sundials_include():
    """The prefix whose include/cvode/cvode.h exists (SUNDIALS_PREFIX, /usr, /usr/local), or None."""
    return next((d for d in [os.environ.get("SUNDIALS_PREFIX", ""), "/usr", "/usr/local"]
                 if d and (Path(d) / "include" / "cvode" / "cvode.h").is_file()), None)


def test_make_cvode_links_with_the_installed_sundials(tmp_path, tools, scenes, references):
    """`make cvode` with the SUNDIALS installed (Debian's 6.x has no libsundials_core: the
    Makefile links it only where the compiler finds it); the example agrees with lagcodegen's
    CVODE."""
    if sundials_include() is None:
        pytest.skip("no SUNDIALS headers (cvode/cvode.h) installed")
    s = SETUPS["double_pendulum"]
    write_bundle(scenes["double_pendulum"], tmp_path, lang="c", y0=s["y0"], params=s["params"], t_end=s["t_end"])
    run(["make", "cvode"], tmp_path)
    _, final = last_row(run(["./cvode_example", "-r", "1e-10", "-a", "1e-12"], tmp_path).stdout)
    np.testing.assert_allclose(final[1:5], references["double_pendulum", "default"], rtol=0, atol=1e-6)


def test_make_clean_removes_everything_make_wrote(tmp_path, tools, scenes):
    m = lcg.Model("cp")
    x, y = m.coordinates("x y")
    m.particle("bob", 1.0, (x, y))
    m.gravity(9.81)
    bundles = {"c": (scenes["oscillator"], dict(lang="c")), "fortran": (scenes["oscillator"], dict(lang="fortran")),
               "constrained": (lcg.ConstrainedSystem(m, holonomic=[x**2 + y**2 - 1]), dict(y0=[0.6, -0.8, 0, 0]))}
    for name, (scene, options) in bundles.items():
        folder = tmp_path / name
        write_bundle(scene, folder, **options)
        written = sorted(p.name for p in folder.iterdir())
        run(["make"], folder)
        check = run(["make", "check"], folder)
        assert "make check: rk4_example agrees with reference.csv" in check.stdout, (name, check.stdout)
        if name == "c" and sundials_include() is not None:
            run(["make", "cvode"], folder)
        assert len(list(folder.iterdir())) > len(written) + 3  # the library, objects, examples, CSVs
        run(["make", "clean"], folder)
        assert sorted(p.name for p in folder.iterdir()) == written, name


def test_bad_options_write_nothing(tmp_path, scenes):
    scene = scenes["oscillator"]
    target = tmp_path / "out"
    for kwargs in (dict(lang="cobol"), dict(y0=[1.0, 2.0, 3.0]), dict(params={"nope": 1.0}),
                   dict(t_end=-1.0), dict(steps=0)):
        with pytest.raises(ModelError):
            write_bundle(scene, target, **kwargs)
        assert not target.exists()


def test_generate_bundle_check_from_the_command_line(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    model = str(ROOT / "examples" / "damped_driven_oscillator.toml")
    base = [sys.executable, "-m", "lagcodegen", "generate", model, "-o", str(tmp_path), "--lang", "fortran",
            "--bundle", "-q"]
    assert run(base, ROOT, env=env, check=False).returncode == 0
    names = sorted(p.name for p in tmp_path.iterdir())
    assert {"Makefile", "CMakeLists.txt", "README.md", "rk4_example.c"} <= set(names)
    assert any(n.endswith(".f90") for n in names) and not any(n.endswith(".c") and n[:-2] + ".h" in names
                                                               for n in names)
    assert run([*base, "--check"], ROOT, env=env, check=False).returncode == 0
    readme = tmp_path / "README.md"
    readme.write_text(readme.read_text() + "edited\n")
    proc = run([*base, "--check"], ROOT, env=env, check=False)
    assert proc.returncode == 5 and "README.md" in proc.stderr
    assert run(base, ROOT, env=env, check=False).returncode == 0
    assert run([*base, "--check"], ROOT, env=env, check=False).returncode == 0


def test_without_a_reference_make_check_says_so(tmp_path, tools, scenes, monkeypatch):
    """Where lagcodegen cannot run the model when it writes the bundle (here: a reference run that
    fails, its message on several lines with quotes and dollars), the bundle has no
    reference.csv and make check and the README say why."""
    from lagcodegen.codegen import bundle

    def broken(*args):
        raise lcg.LagcodegenError('cc: not found\n  "$HOME" `x` \\ second line')

    monkeypatch.setitem(bundle.REFERENCE_RUNS, "scene", broken)
    write_bundle(scenes["oscillator"], tmp_path, sundials_example=False)
    assert not (tmp_path / "reference.csv").exists()
    assert "`make check` compares nothing: there is no `reference.csv`" in (tmp_path / "README.md").read_text()
    run(["make"], tmp_path)
    check = run(["make", "check"], tmp_path)
    assert ("make check: no reference.csv to compare with (lagcodegen could not run the model when it wrote the "
            "bundle: cc: not found 'HOME' 'x' / second line)") in check.stdout
    assert (tmp_path / "rk4_example.csv").is_file()


@pytest.mark.parametrize("lang", ["c", "fortran"])
def test_a_floating_body_bundle_integrates_its_quaternion(tmp_path, tools, lang):
    """A model with generalized speeds (a free body on a quaternion ball joint) bundles with its
    nq + nv states: `make check` passes, and the RK4 example's final state agrees with
    lagcodegen's CVODE."""
    m = lcg.Model("spinner")
    m.link("body", joint=lcg.Joint.spherical("ball"), mass=1.0, inertia=(1.0, 2.0, 3.0))
    scene = Scene(derive(m), jacobian=False, outputs=["energy"])
    y0 = [0.0, 0.0, 0.0, 1.0, 0.01, 2.0, 0.01]
    write_bundle(scene, tmp_path, lang=lang, y0=y0, t_end=5.0)
    run(["make"], tmp_path)
    check = run(["make", "check"], tmp_path)
    assert "agrees with reference.csv" in check.stdout
    header, final = last_row((tmp_path / "rk4_example.csv").read_text())
    assert header[1:8] == ["ball_qx", "ball_qy", "ball_qz", "ball_qw", "ball_wx", "ball_wy", "ball_wz"]
    ref = lcg.build_code(generate_c(scene)).simulate([0.0, 5.0], y0=y0, rtol=1e-12, atol=1e-14).y[-1]
    np.testing.assert_allclose(final[1:8], ref, rtol=0, atol=1e-6)
