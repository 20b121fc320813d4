"""Input tables on the command line: `lagcodegen simulate ... --input NAME=FILE[:KIND]` and
`lagcodegen sweep ... --input ...` (the same table for every member) against the analytic step
response of a damped oscillator; bad files and names are usage errors naming the input."""

import numpy as np

from lagcodegen.cli import main

FORCED = """
[model]
name = "forced_cli"
coordinates = ["x"]

[parameters]
m = 1.0
k = 4.0
c = 0.4

[inputs]
F = 0.0

[[particles]]
name = "mass"
mass = "m"
position = ["x", 0]

[energy]
potential = "k*x**2/2"
dissipation = "c*x_dot**2/2"

[[generalized_forces]]
coordinate = "x"
expr = "F"

[simulation]
t_end = 10.0
n_out = 101
rtol = 1e-10
atol = 1e-12
initial = { x = 0.0 }
"""


def step_response(t, k, t_step=1.3, F0=2.0, m=1.0, c=0.4):
    w0, zeta = np.sqrt(k / m), c / (2 * np.sqrt(k * m))
    wd = w0 * np.sqrt(1 - zeta ** 2)
    s = np.clip(t - t_step, 0.0, None)
    x = F0 / k * (1 - np.exp(-zeta * w0 * s) * (np.cos(wd * s) + zeta / np.sqrt(1 - zeta ** 2) * np.sin(wd * s)))
    return np.where(t >= t_step, x, 0.0)


def test_simulate_and_sweep_take_input_tables(tmp_path, capsys):
    model = tmp_path / "forced.toml"
    model.write_text(FORCED)
    (tmp_path / "step.txt").write_text("0 0\n1.3 2\n")
    out = tmp_path / "r.csv"
    assert main(["simulate", str(model), "-o", str(out), "--input", f"F={tmp_path / 'step.txt'}:zoh", "-q"]) == 0
    res = np.genfromtxt(out, delimiter=",", names=True)
    assert np.max(np.abs(res["x"] - step_response(res["t"], 4.0))) < 1e-8
    table = tmp_path / "s.csv"
    assert main(["sweep", str(model), "-o", str(table), "--grid", "k=2:6:3", "--input",
                 f"F={tmp_path / 'step.txt'}:zoh", "-q"]) == 0
    rows = np.genfromtxt(table, delimiter=",", names=True)
    assert np.allclose(rows["final_x"], step_response(10.0, rows["k"]), rtol=0, atol=1e-8)
    # a linear table (the default kind) ramps the force: a different answer
    assert main(["simulate", str(model), "-o", str(out), "--input", f"F={tmp_path / 'step.txt'}", "-q"]) == 0
    ramp = np.genfromtxt(out, delimiter=",", names=True)
    assert np.max(np.abs(ramp["x"] - res["x"])) > 1e-2
    capsys.readouterr()
    assert main(["simulate", str(model), "-o", str(out), "--input", f"F={tmp_path / 'none.txt'}", "-q"]) == 2
    assert "--input F: cannot read" in capsys.readouterr().err
    (tmp_path / "bad.txt").write_text("0 0\n2 1\n1 3\n")
    assert main(["simulate", str(model), "-o", str(out), "--input", f"F={tmp_path / 'bad.txt'}", "-q"]) == 2
    assert "--input F: times must increase strictly" in capsys.readouterr().err
    assert main(["simulate", str(model), "-o", str(out), "--input", "F", "-q"]) == 2
