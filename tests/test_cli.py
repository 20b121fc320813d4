"""The lagcodegen command: each subcommand end to end, and its exit codes."""

import subprocess
import time
import uuid
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


def run(*args, cwd=None):
    import os
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "lagcodegen", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd, env=env, timeout=600)


def test_simulate_writes_csv_and_png(tmp_path):
    proc = run("simulate", EXAMPLES / "double_pendulum.toml", "-o", tmp_path / "dp.csv", "--plot",
               tmp_path / "dp.png", "--t-end", "2")
    assert proc.returncode == 0, proc.stderr
    assert "integrated" in proc.stderr and "energy drift" in proc.stderr  # progress is shown
    header = (tmp_path / "dp.csv").read_text().splitlines()[0].split(",")
    assert header[:5] == ["t", "theta1", "theta2", "theta1_dot", "theta2_dot"] and "energy" in header
    data = np.loadtxt(tmp_path / "dp.csv", delimiter=",", skiprows=1)
    assert data[-1, 0] == pytest.approx(2.0)
    energy = data[:, header.index("energy")]
    assert np.max(np.abs(energy - energy[0])) < 1e-7
    assert (tmp_path / "dp.png").read_bytes()[:4] == b"\x89PNG"


def test_simulate_npz_with_parameter_override(tmp_path):
    proc = run("simulate", EXAMPLES / "pendulum.toml", "-o", tmp_path / "p.npz", "--set", "g=1.62",
               "--t-end", "1", "--backend", "sksundae", "-q")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    data = np.load(tmp_path / "p.npz")
    assert data["t"][-1] == 1.0 and np.all(np.isfinite(data["theta"]))


def test_generate_and_check(tmp_path):
    out = tmp_path / "gen"
    assert run("generate", EXAMPLES / "pendulum.toml", "-o", out, "-q").returncode == 0
    assert (out / "pendulum.h").is_file() and (out / "pendulum.c").is_file()
    assert run("generate", EXAMPLES / "pendulum.toml", "-o", out, "--check", "-q").returncode == 0
    (out / "pendulum.c").write_text((out / "pendulum.c").read_text() + "\n")
    proc = run("generate", EXAMPLES / "pendulum.toml", "-o", out, "--check")
    assert proc.returncode == 5 and "out of date" in proc.stderr


def test_generate_folds_parameters(tmp_path):
    out = tmp_path / "gen"
    assert run("generate", EXAMPLES / "pendulum.toml", "-o", out, "--fold-all", "-q").returncode == 0
    header = (out / "pendulum.h").read_text()
    assert "#define PENDULUM_NP 0" in header and "g = 9.81" in header


def test_info_prints_the_equations():
    proc = run("info", EXAMPLES / "pendulum.toml")
    assert proc.returncode == 0, proc.stderr
    assert "mass matrix" in proc.stdout and "l**2*m" in proc.stdout.replace(" ", "").replace("\n", "") or \
        "2\nl *m" in proc.stdout
    latex = run("info", EXAMPLES / "pendulum.toml", "--latex")
    assert "\\sin" in latex.stdout


def test_bad_model_file_exit_code_and_message(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[model]\ncoordinates = ["x"]\n[[particles]]\nname = "p"\nmass = 1\n'
                   'position = ["x*zeta", "0"]\n')
    proc = run("simulate", bad, "-o", tmp_path / "o.csv")
    assert proc.returncode == 1
    assert "bad.toml" in proc.stderr and "zeta" in proc.stderr and "particles[0].position[0]" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_usage_error_exit_code():
    assert run("simulate").returncode == 2


# ---------------------------------------------------------------------- constrained model files
def read_csv(path):
    header = path.read_text().splitlines()[0].split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {name: data[:, i] for i, name in enumerate(header)}


@pytest.fixture(scope="module")
def angle_pendulum():
    """lagcodegen.systems.pendulum from theta = 1 at rest (the Cartesian example's initial state)."""
    import lagcodegen as lcg
    sim = lcg.compile_model(lcg.systems.pendulum(), outputs=["positions"])
    return lambda t: sim.simulate(t, q0=[1.0], rtol=1e-12, atol=1e-14)


def test_simulate_constrained_pendulum_matches_the_angle_model(tmp_path, angle_pendulum):
    proc = run("simulate", EXAMPLES / "cartesian_pendulum.toml", "-o", tmp_path / "cp.csv", "--plot",
               tmp_path / "cp.png")
    assert proc.returncode == 0, proc.stderr
    assert "formulation index1" in proc.stderr and "largest constraint residual" in proc.stderr
    cols = read_csv(tmp_path / "cp.csv")
    assert list(cols)[:5] == ["t", "x", "y", "x_dot", "y_dot"]
    assert {"energy", "tension", "bob_x", "lambda_0", "g_0", "gdot_0"} <= set(cols)
    ref = angle_pendulum(cols["t"])
    theta = np.arctan2(cols["x"], -cols["y"])
    assert np.max(np.abs(theta - ref["theta"])) < 1e-6
    # Rod tension from the multiplier: f = x^2 + y^2 - l^2, so T = -2 l lambda = m (g cos(theta) + l theta'^2).
    l, m, g = 1.0, 1.0, 9.81
    tension = -2 * l * cols["lambda_0"]
    assert np.max(np.abs(tension - m * (g * np.cos(ref["theta"]) + l * ref["theta_dot"] ** 2))) < 1e-6
    assert np.max(np.abs(tension - cols["tension"])) < 1e-6  # the file's own output, from the state
    assert np.max(np.abs(cols["g_0"])) < 1e-8 and np.ptp(cols["energy"]) < 1e-7
    assert (tmp_path / "cp.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("formulation", ["ggl", "minimal"])
def test_simulate_constrained_formulation_override(tmp_path, angle_pendulum, formulation):
    proc = run("simulate", EXAMPLES / "cartesian_pendulum.toml", "-o", tmp_path / "cp.npz", "--t-end", "2",
               "--n-out", "101", "--formulation", formulation)
    assert proc.returncode == 0, proc.stderr
    assert f"formulation {formulation}" in proc.stderr and "ignoring the file's baumgarte" in proc.stderr
    data = np.load(tmp_path / "cp.npz")
    ref = angle_pendulum(data["t"])
    assert data["t"][-1] == 2.0
    assert np.max(np.abs(np.arctan2(data["x"], -data["y"]) - ref["theta"])) < 1e-6
    assert ("lambda_0" in data.files) == (formulation != "minimal") and "g_0" in data.files


def test_simulate_reports_the_terminal_event(tmp_path):
    proc = run("simulate", EXAMPLES / "sliding_off_sphere.toml", "-o", tmp_path / "s.csv")
    assert proc.returncode == 0, proc.stderr
    line = next(ln for ln in proc.stderr.splitlines() if "event leave" in ln)
    t_event = float(line.split("t = ")[1].split()[0])
    assert "terminal" in line
    cols = read_csv(tmp_path / "s.csv")
    assert cols["t"][-1] == pytest.approx(t_event, abs=1e-9) and t_event < 3.2  # the run stops there
    cos_theta = cols["y"][-1] / 1.0  # R = 1
    v0, g = 1e-3, 9.81
    assert cos_theta == pytest.approx((2 + v0 ** 2 / g) / 3, abs=1e-8)
    assert cos_theta == pytest.approx(2 / 3, abs=1e-6)
    assert abs(cols["lambda_0"][-1]) < 1e-6 and np.all(cols["lambda_0"][:-1] > 0)
    quiet = run("simulate", EXAMPLES / "sliding_off_sphere.toml", "-o", tmp_path / "s2.csv", "-q")
    assert quiet.returncode == 0 and quiet.stderr == ""


def test_generate_constrained_sources_and_check(tmp_path):
    out = tmp_path / "gen"
    proc = run("generate", EXAMPLES / "cartesian_pendulum.toml", "-o", out, "-q")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["cartesian_pendulum.lagcodegen.json", "cartesian_pendulum_dae.c",
                                                     "cartesian_pendulum_dae.h"]  # with the manifest
    header = (out / "cartesian_pendulum_dae.h").read_text()
    assert "cartesian_pendulum_kkt" in header and "cartesian_pendulum_crhs" in header
    assert run("generate", EXAMPLES / "cartesian_pendulum.toml", "-o", out, "--check", "-q").returncode == 0
    # other options, other code: the folder is out of date
    proc = run("generate", EXAMPLES / "cartesian_pendulum.toml", "-o", out, "--check", "--formulation", "ggl")
    assert proc.returncode == 5 and "cartesian_pendulum_dae.c" in proc.stderr
    (out / "cartesian_pendulum_dae.h").write_text(header + "\n")
    proc = run("generate", EXAMPLES / "cartesian_pendulum.toml", "-o", out, "--check")
    assert proc.returncode == 5 and "out of date" in proc.stderr
    # events become root functions; Fortran
    sphere = tmp_path / "sphere"
    assert run("generate", EXAMPLES / "sliding_off_sphere.toml", "-o", sphere, "--lang", "fortran", "-q") \
        .returncode == 0
    assert sorted(p.name for p in sphere.iterdir()) == ["sliding_off_sphere.lagcodegen.json",
                                                        "sliding_off_sphere_dae.f90", "sliding_off_sphere_dae.h"]
    assert "leave: lambda_0" in (sphere / "sliding_off_sphere_dae.h").read_text()


def test_generate_constrained_bundle_builds_and_runs(tmp_path, angle_pendulum):
    import shutil
    if shutil.which("make") is None:
        pytest.fail("the bundle test needs make")
    out = tmp_path / "bundle"
    proc = run("generate", EXAMPLES / "cartesian_pendulum.toml", "-o", out, "--bundle", "-q")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["CMakeLists.txt", "Makefile", "README.md", "rk4_example.c", "cartesian_pendulum_dae.c",
         "cartesian_pendulum_dae.h", "cartesian_pendulum.lagcodegen.json", "reference.csv"])
    build = subprocess.run(["make", "check"], cwd=out, capture_output=True, text=True, timeout=300, check=False)
    assert build.returncode == 0, build.stdout + build.stderr
    assert "make check: rk4_example agrees with reference.csv" in build.stdout
    cols = read_csv(out / "rk4_example.csv")  # the file's t_end, initial state and Baumgarte (5, 5)
    assert {"lambda_0", "g_0", "tension"} <= set(cols) and cols["t"][-1] == 10.0
    ref = angle_pendulum([0.0, 10.0])
    assert cols["x"][-1] == pytest.approx(ref["bob_x"][-1], abs=1e-6)
    assert cols["y"][-1] == pytest.approx(ref["bob_y"][-1], abs=1e-6)
    assert run("generate", EXAMPLES / "cartesian_pendulum.toml", "-o", out, "--bundle", "--check", "-q") \
        .returncode == 0


def test_info_prints_constraints_and_multiplier_equations():
    proc = run("info", EXAMPLES / "cartesian_pendulum.toml")
    assert proc.returncode == 0, proc.stderr
    text = proc.stdout
    assert "1 holonomic, 0 nonholonomic" in text and "multipliers: lambda_0" in text
    assert "differential form (eq. 4.2)" in text and "[2*x  2*y]" in text
    assert "equations with multipliers (eq. 4.5)" in text
    assert "-2*lambda_0*x + m*x_ddot" in text and "g*m - 2*lambda_0*y + m*y_ddot" in text
    sphere = run("info", EXAMPLES / "sliding_off_sphere.toml", "--latex")
    assert sphere.returncode == 0 and "event leave (decreasing, terminal)" in sphere.stdout
    assert "\\lambda_{0}" in sphere.stdout


def test_constrained_file_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text((EXAMPLES / "cartesian_pendulum.toml").read_text().replace('"index1"', '"index2"'))
    proc = run("simulate", bad, "-o", tmp_path / "o.csv")
    assert proc.returncode == 1
    assert "bad.toml" in proc.stderr and "simulation.formulation" in proc.stderr and "'index2'" in proc.stderr
    assert "Traceback" not in proc.stderr
    proc = run("simulate", EXAMPLES / "cartesian_pendulum.toml", "-o", tmp_path / "o.csv", "--formulation", "dae")
    assert proc.returncode == 2
    # inconsistent initial state: the solver's check, exit 1
    bad.write_text((EXAMPLES / "cartesian_pendulum.toml").read_text().replace('x = "sin(1)"', 'x = 0.5'))
    proc = run("simulate", bad, "-o", tmp_path / "o.csv", "-q")
    assert proc.returncode == 1 and "inconsistent initial conditions" in proc.stderr


def test_project_initial_state_onto_the_constraints(tmp_path):
    base = ["simulate", EXAMPLES / "cartesian_pendulum.toml", "-o", tmp_path / "cp.csv", "--set", "l=1.5",
            "--t-end", "1", "-q"]
    refused = run(*base)
    assert refused.returncode == 1 and "--project-initial" in refused.stderr
    assert run(*base, "--project-initial").returncode == 0
    header = (tmp_path / "cp.csv").read_text().splitlines()[0].split(",")
    data = np.loadtxt(tmp_path / "cp.csv", delimiter=",", skiprows=1)
    x, y = data[:, header.index("x")], data[:, header.index("y")]
    assert np.max(np.abs(np.hypot(x, y) - 1.5)) < 1e-6


@pytest.mark.parametrize("extra, message", [
    (["-o", "x.txt"], "results are written as .csv or .npz"),
    (["-o", "{tmp}"], "is a folder"),
    (["-o", "r.csv", "--n-out", "-5"], "--n-out -5"),
    (["-o", "r.csv", "--n-out", "100000000000000"], "--n-out"),
    (["-o", "r.csv", "--max-steps", "0"], "--max-steps 0"),
    (["-o", "r.csv", "--rtol", "nan"], "--rtol nan"),
    (["-o", "r.csv", "--t-end", "-1"], "--t-end -1"),
    (["-o", "r.csv", "--plot", "p.jpg"], "plots are written as .png"),
])
def test_simulate_options_are_checked_before_any_work(tmp_path, extra, message, monkeypatch):
    """Refused before deriving or compiling: the compile steps are replaced by ones that fail the
    test if reached (this test used to bound the wall time, which a loaded machine broke)."""
    from lagcodegen.cli import main
    from lagcodegen.cli import simulate as cli_simulate

    def reached(*args, **kwargs):
        raise AssertionError("the model was compiled before the options were checked")

    for name in ("compile_file", "compile_urdf", "compile_urdf_file"):
        if hasattr(cli_simulate, name):
            monkeypatch.setattr(cli_simulate, name, reached)
    args = ["simulate", str(ROOT / "examples" / "pendulum.toml")] + [a.replace("{tmp}", str(tmp_path)) for a in extra]
    code = main(args)
    assert code == 2
    assert not (tmp_path / "r.csv").exists()


def test_simulate_n_out_two_gives_two_rows_and_taylor_method(tmp_path):
    from lagcodegen.cli import main
    out = tmp_path / "r.csv"
    assert main(["simulate", str(ROOT / "examples" / "pendulum.toml"), "-o", str(out), "--n-out", "2",
                 "--method", "taylor", "-q"]) == 0
    rows = out.read_text().strip().splitlines()
    assert len(rows) == 3  # header + 2 output times


SIGTERM_WHILE_WRITING = """
import os, signal, sys, time
from lagcodegen import cli
from lagcodegen.result import Result

real_replace = os.replace

def sigterm_before_replace(src, dst):  # the temporary file is complete: SIGTERM arrives now
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(10)
    real_replace(src, dst)

method = getattr(Result, sys.argv[1])

def writing(self, *args, **kwargs):
    os.replace = sigterm_before_replace
    return method(self, *args, **kwargs)

setattr(Result, sys.argv[1], writing)
sys.exit(cli.main(sys.argv[2:]))
"""


@pytest.mark.parametrize("method, name", [("save", "r.csv"), ("save", "r.npz"), ("plot", "r.png")])
def test_sigterm_while_writing_leaves_no_temporary_file(tmp_path, method, name):
    import os
    out = tmp_path / "out"
    out.mkdir()
    args = ["simulate", EXAMPLES / "pendulum.toml", "-q", "--t-end", "0.1", "-o",
            out / ("r.csv" if method == "plot" else name)]
    if method == "plot":
        args += ["--plot", out / name]
    proc = subprocess.run([sys.executable, "-c", SIGTERM_WHILE_WRITING, method, *map(str, args)],
                          capture_output=True, text=True, timeout=600, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 143, proc.stderr
    assert "terminated" in proc.stderr and "Traceback" not in proc.stderr
    left = sorted(p.name for p in out.iterdir())
    assert left == [], left  # no .tmp file, no partial output, and no CSV without its plot


def test_set_of_an_unknown_parameter_is_refused(tmp_path):
    from lagcodegen.cli import main
    for model in ("pendulum.toml", "cartesian_pendulum.toml"):
        for command in (["simulate", "-o", str(tmp_path / "r.csv")], ["generate", "-o", str(tmp_path / "gen")]):
            for item in ("G=1.62", "zz=1"):
                start = time.perf_counter()
                assert main([command[0], str(EXAMPLES / model), *command[1:], "--set", item, "-q"]) == 2
                assert time.perf_counter() - start < 2  # before deriving or compiling
    assert not (tmp_path / "r.csv").exists() and not (tmp_path / "gen").exists()


def test_set_message_names_the_parameters(capsys):
    from lagcodegen.cli import main
    assert main(["simulate", str(EXAMPLES / "pendulum.toml"), "-o", "r.csv", "--set", "G=1.62"]) == 2
    err = capsys.readouterr().err
    assert "--set G: not a parameter of pendulum; did you mean 'g'? (parameters: l, g, m)" in err
    assert main(["simulate", str(EXAMPLES / "pendulum.toml"), "-o", "r.csv", "--set", "g"]) == 2
    assert "--set expects NAME=VALUE, got 'g'" in capsys.readouterr().err


def test_max_steps_from_the_model_file(tmp_path):
    from lagcodegen.cli import main
    text = (EXAMPLES / "pendulum.toml").read_text().replace('method = "adams"', 'method = "adams"\nmax_steps = 5')
    model = tmp_path / "p.toml"
    model.write_text(text)
    for backend in ("native", "sksundae"):
        assert main(["simulate", str(model), "-o", str(tmp_path / "r.csv"), "-q", "--backend", backend]) == 4
        assert main(["simulate", str(model), "-o", str(tmp_path / "r.csv"), "-q", "--backend", backend,
                     "--max-steps", "100000"]) == 0


@pytest.mark.parametrize("command", ["generate", "simulate", "sweep"])
def test_progress_flags_are_accepted(command):
    from lagcodegen.cli import _show_progress, parser
    base = [command, "m.toml", "-o", "out.csv" if command != "generate" else "out"]
    assert parser().parse_args(base + ["--progress"]).progress is True
    assert parser().parse_args(base + ["--no-progress"]).progress is False
    args = parser().parse_args(base)
    assert args.progress is None
    assert _show_progress(parser().parse_args(base + ["--progress", "-q"])) is True  # asked for: shown
    assert _show_progress(parser().parse_args(base + ["--no-progress"])) is False


def test_progress_lines_name_the_stages(tmp_path, capsys, monkeypatch):
    """--progress: a line per long stage (here every stage, AFTER = 0); --no-progress and the default
    off a terminal (pytest's stderr): none."""
    from lagcodegen import progress
    from lagcodegen.cli import main
    monkeypatch.setattr(progress, "AFTER", 0.0)
    model = EXAMPLES / "double_pendulum.toml"
    assert main(["generate", str(model), "-o", str(tmp_path / "gen"), "--progress", "-q"]) == 0
    err = capsys.readouterr().err
    assert "lagcodegen: derive 0/2 coordinates, " in err and "lagcodegen: derive 2/2 coordinates, " in err
    assert "lagcodegen: formulate " in err
    for flags in (["--no-progress"], []):
        assert main(["generate", str(model), "-o", str(tmp_path / f"gen{len(flags)}"), *flags]) == 0
        assert "lagcodegen: derive " not in capsys.readouterr().err
    # a model of its own (the pipeline cache would load one compiled before without deriving it)
    fresh = tmp_path / "double_pendulum.toml"
    fresh.write_text(model.read_text().replace("l2 = 1.0", f"l2 = {1 + int(uuid.uuid4().hex[:8], 16) / 1e12!r}"))
    assert main(["simulate", str(fresh), "-o", str(tmp_path / "r.csv"), "--t-end", "0.1", "--progress"]) == 0
    err = capsys.readouterr().err
    assert err.index("lagcodegen: build model 'double_pendulum' (not cached), ") < err.index("integrated")
    assert main(["simulate", str(fresh), "-o", str(tmp_path / "r.csv"), "--t-end", "0.1", "--progress"]) == 0
    err = capsys.readouterr().err  # again: from the cache, no build line
    assert "lagcodegen: build " not in err and "from the cache (nothing derived)" in err
    single = tmp_path / "pendulum.toml"
    mass = 1 + int(uuid.uuid4().hex[:8], 16) / 1e12  # a model of its own, as above
    single.write_text((EXAMPLES / "pendulum.toml").read_text().replace("m = 1.0", f"m = {mass!r}"))
    assert main(["sweep", str(single), "--grid", "g=9.7:9.9:3", "-o", str(tmp_path / "s.csv"),
                 "--t-end", "0.1", "--progress", "-q"]) == 0
    assert "lagcodegen: build model 'pendulum' (not cached)" in capsys.readouterr().err


def test_model_paths_are_read_by_the_loader_of_their_suffix(tmp_path, capsys):
    """One dispatch (modelfile.load_model_path) for every command: a .toml file (any case of the
    suffix) is a TOML model file; another suffix is refused naming the ones known, exit 1."""
    import lagcodegen as lcg
    from lagcodegen.cli import main
    from lagcodegen.modelfile import LOADERS, load_model_path
    assert ".toml" in LOADERS
    upper = tmp_path / "P.TOML"
    upper.write_text((EXAMPLES / "pendulum.toml").read_text())
    mf = load_model_path(upper)
    assert [q.name for q in mf.model.coords] == ["theta"] and mf.path == upper
    other = tmp_path / "pendulum.txt"
    other.write_text((EXAMPLES / "pendulum.toml").read_text())
    with pytest.raises(lcg.ModelError, match=r"pendulum.txt: not a model file .*\.toml"):
        load_model_path(other)
    for command in (["info"], ["simulate", "-o", str(tmp_path / "r.csv")], ["generate", "-o", str(tmp_path / "g")],
                    ["sweep", "--grid", "g=1:2:2", "-o", str(tmp_path / "s.csv")]):
        assert main([command[0], str(other), *command[1:], "-q"] if command[0] != "info" else ["info", str(other)]) == 1
        assert "pendulum.txt: not a model file" in capsys.readouterr().err
    assert not any(tmp_path.glob("r.csv")) and not (tmp_path / "g").exists()


def test_generate_writes_what_the_api_renders(tmp_path):
    """`generate` writes lagcodegen.generate_file's files (plus the manifest), with the command
    line applied to the file's settings: the same texts from Python as from the command line."""
    import dataclasses

    import lagcodegen as lcg
    from lagcodegen.cli import main
    model = EXAMPLES / "cartesian_pendulum.toml"
    for flags, settings, kwargs in [
            ([], {}, {}),
            (["--formulation", "minimal", "--fold-all"], {"formulation": "minimal", "runtime_parameters": []}, {}),
            (["--bundle", "--lang", "fortran", "--set", "g=1.5"], {}, {"bundle": True, "lang": "fortran"})]:
        out = tmp_path / f"gen{len(flags)}"
        assert main(["generate", str(model), "-o", str(out), "-q", *flags]) == 0
        mf = lcg.modelfile.load_model_path(model)
        parameters = {**mf.simulation.parameters, **({"g": 1.5} if "--set" in flags else {})}
        mf = dataclasses.replace(mf, simulation=dataclasses.replace(mf.simulation, parameters=parameters, **settings))
        files = lcg.generate_file(mf, **kwargs)
        written = {p.name: p.read_text() for p in out.iterdir() if not p.name.endswith(".lagcodegen.json")}
        assert written == files and files


def test_simulate_and_info_report_the_events_of_a_plain_file(tmp_path):
    """A file without constraints with [[events]]: info shows them, simulate locates them (CVODE)
    and reports each; the terminal one ends the written trajectory."""
    from scipy.special import ellipk
    text = (EXAMPLES / "pendulum.toml").read_text() + """
[[events]]
name = "down"
expr = "theta"
direction = -1
terminal = false

[[events]]
name = "stop"
expr = "p_theta"
direction = 1
"""
    text = text.replace('method = "adams"', 'method = "adams"\nrtol = 1e-12\natol = 1e-14')
    path = tmp_path / "pendulum_events.toml"
    path.write_text(text)
    info = run("info", path)
    assert info.returncode == 0, info.stderr
    assert "event down (decreasing): zero of" in info.stdout and "event stop (increasing, terminal)" in info.stdout
    proc = run("simulate", path, "-o", tmp_path / "e.csv")
    assert proc.returncode == 0, proc.stderr
    T = 4 * ellipk(np.sin(0.5) ** 2) / np.sqrt(9.81)  # theta0 = 1: down at T/4, p_theta rises through 0 at T/2
    lines = [ln.split(": ", 1)[1] for ln in proc.stderr.splitlines() if ln.startswith("lagcodegen: event ")]
    assert [ln.split()[1] for ln in lines] == ["down", "stop"]
    assert float(lines[0].split()[5]) == pytest.approx(T / 4, rel=1e-9)
    assert "terminal: run stopped" in lines[1] and float(lines[1].split()[5]) == pytest.approx(T / 2, rel=1e-9)
    data = np.loadtxt(tmp_path / "e.csv", delimiter=",", skiprows=1)
    assert data[-1, 0] == pytest.approx(T / 2, rel=1e-9)


def test_fit_recovers_the_pendulum_length(tmp_path):
    """lagcodegen fit: the pendulum of examples/pendulum.toml (l = 1 in the file) fitted to theta
    measured on a pendulum of length 1.3 (noise 0.005, seeded): l within 3 standard errors, the
    estimates as CSV, the data against the fit as PNG."""
    import lagcodegen as lcg
    sim = lcg.compile_model(lcg.systems.pendulum())
    t = np.linspace(0.0, 5.0, 101)
    theta = sim.simulate(t, q0=[1.0], params={"l": 1.3}, rtol=1e-11, atol=1e-13)["theta"]
    theta = theta + 0.005 * np.random.default_rng(7).standard_normal(t.size)
    data = tmp_path / "data.csv"
    data.write_text("t,theta\n" + "\n".join(f"{float(a)!r},{float(b)!r}" for a, b in zip(t, theta)) + "\n")
    proc = run("fit", EXAMPLES / "pendulum.toml", data, "--fit", "l", "--sigma", "0.005", "-o", tmp_path / "fit.csv",
               "--plot", tmp_path / "fit.png")
    assert proc.returncode == 0, proc.stderr
    assert "fitted l" in proc.stderr
    rows = (tmp_path / "fit.csv").read_text().splitlines()
    assert rows[0] == "name,estimate,stderr"
    name, est, err = rows[1].split(",")
    assert name == "l" and abs(float(est) - 1.3) < 3 * float(err) and 0 < float(err) < 0.01
    assert (tmp_path / "fit.png").read_bytes()[:4] == b"\x89PNG"
    # bad input: an unknown name, a data column the model lacks
    bad = run("fit", EXAMPLES / "pendulum.toml", data, "--fit", "length")
    assert bad.returncode == 2 and "length" in bad.stderr
    (tmp_path / "bad.csv").write_text("t,phi\n0,1\n1,2\n")
    bad = run("fit", EXAMPLES / "pendulum.toml", tmp_path / "bad.csv", "--fit", "l")
    assert bad.returncode == 1 and "'phi' is neither a state nor an output" in bad.stderr


def test_fit_interrupted_while_plotting_leaves_no_estimates(tmp_path, monkeypatch):
    """The estimates and the plot appear together: Ctrl-C while plotting leaves neither."""
    import lagcodegen as lcg
    from lagcodegen.cli import fit as fit_command
    from lagcodegen.cli import main
    t = np.linspace(0.0, 2.0, 21)
    data = tmp_path / "data.csv"
    res = lcg.compile_model(lcg.systems.pendulum()).simulate(t, q0=[1.0], params={"l": 1.2})
    data.write_text("t,theta\n" + "".join(f"{a!r},{b!r}\n" for a, b in zip(t.tolist(), res["theta"].tolist())))

    def interrupted(*args):
        raise KeyboardInterrupt
    monkeypatch.setattr(fit_command, "_plot", interrupted)
    assert main(["fit", str(EXAMPLES / "pendulum.toml"), str(data), "--fit", "l", "-o", str(tmp_path / "fit.csv"),
                 "--plot", str(tmp_path / "fit.png"), "-q"]) == 130
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data.csv"]
