"""The lagcodegen command: each subcommand end to end, and its exit codes."""

import subprocess
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
