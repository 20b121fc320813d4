"""Bundles of models with inputs: lcg_inputs.h/.c ship with them and inputs_example.c (RK4, the
inputs read from table files, steps cut at the breakpoints) builds with make and strict flags;
a step force (zero-order hold) and a ramp (linear) give the analytic responses of the damped
oscillator. Models without inputs keep their bundles as they were (the corpus check)."""

import subprocess
import sys
from pathlib import Path

import numpy as np

import lagcodegen as lcg
from helpers import STRICT_CFLAGS
from lagcodegen.codegen.bundle import render_bundle

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "simulation"))
from test_input_tables import oscillator, step_response  # noqa: E402


def run(cmd, cwd, **kw):
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, **kw)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc


def test_bundle_takes_input_tables_from_c(tmp_path, tools):
    files = render_bundle(lcg.Scene(lcg.derive(oscillator()), outputs=["force"]), "c", sundials_example=False)
    assert {"lcg_inputs.h", "lcg_inputs.c", "lcg_inputs_types.h", "inputs_example.c"} <= set(files)
    assert "## Inputs from tables" in files["README.md"] and "`F` = `p[3]`" in files["README.md"]
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    run(["make", "CFLAGS=" + " ".join(["-O2", *STRICT_CFLAGS]), "inputs_example"], tmp_path)
    (tmp_path / "step.txt").write_text("0 0\n1.3 2\n")
    out = run(["./inputs_example", "-t", "10", "-n", "100", "-k", "zoh", "-u", "F=step.txt", "0", "0"], tmp_path)
    rows = np.loadtxt(out.stdout.splitlines(), delimiter=",")
    t, x, force = rows[:, 0], rows[:, 1], rows[:, 3]
    assert np.max(np.abs(x - step_response(t, 1.3, 2.0))) < 1e-10
    assert np.array_equal(force, np.where(t >= 1.3, 2.0, 0.0))
    # a ramp F = t (linear table): the CVODE driver's run of the same table
    (tmp_path / "ramp.txt").write_text("0 0\n10 10\n")
    out = run(["./inputs_example", "-t", "10", "-n", "50", "-u", "F=ramp.txt", "0", "0"], tmp_path)
    rows = np.loadtxt(out.stdout.splitlines(), delimiter=",")
    ref = lcg.compile_model(oscillator()).simulate(rows[:, 0], q0=[0.0], rtol=1e-11, atol=1e-13,
                                                   inputs={"F": ([0.0, 10.0], [0.0, 10.0])})
    assert np.max(np.abs(rows[:, 1] - ref["x"])) < 1e-9
    assert np.allclose(rows[:, 3], rows[:, 0], rtol=0, atol=1e-12)  # the force column is the ramp
    bad = subprocess.run(["./inputs_example", "-u", "G=step.txt"], cwd=tmp_path, capture_output=True, text=True)
    assert bad.returncode == 2 and "NAME an input of the model" in bad.stderr


def test_bundles_without_inputs_ship_no_tables():
    files = render_bundle(lcg.Scene(lcg.derive(lcg.systems.pendulum())), "c")
    assert not any(name.startswith("lcg_inputs") or name == "inputs_example.c" for name in files)
    assert "inputs_example" not in files["Makefile"]
