"""``lagcodegen sweep``: real ensembles from model files, checked against the physics (the
pendulum's exact and small-amplitude solutions, energy conservation, where a particle leaves a
sphere), reproducible samples, bad options (exit 2, nothing written, no work), Ctrl-C (exit 130,
nothing written) and the PNG."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.special import ellipj, ellipk

from lagcodegen.cli import main
from lagcodegen.sweep import SweepOptionError, SweepSpec, check_options, member_values

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
PENDULUM = EXAMPLES / "pendulum.toml"


def run(*args):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "lagcodegen", "sweep", *map(str, args)], capture_output=True,
                          text=True, env=env, timeout=600)


def read_csv(path):
    header = path.read_text().splitlines()[0].split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {name: data[:, j] for j, name in enumerate(header)}


def exact_pendulum(theta0, omega, t):
    """theta(t) of a pendulum released at rest from theta0: sin(theta/2) = k sn(K - omega t | k^2)."""
    k = np.sin(theta0 / 2)
    m = k ** 2
    sn, _, _, _ = ellipj(ellipk(m) - omega * t, m)
    return 2 * np.arcsin(k * sn)


def test_grid_over_g_matches_the_pendulum_solutions(tmp_path):
    """101 values of g, one run each: the final angle against the exact (elliptic) solution to the
    tolerance, and against theta0 cos(sqrt(g/l) t) to the small-amplitude error O(theta0^3)."""
    out, png = tmp_path / "g.csv", tmp_path / "g.png"
    theta0, t_end = 0.02, 10.0
    proc = run(PENDULUM, "--grid", "g=9.7:9.9:101", "--grid", f"theta={theta0}", "-o", out, "--plot", png,
               "--t-end", t_end, "--rtol", "1e-11", "--atol", "1e-13", "--threads", "2")
    assert proc.returncode == 0, proc.stderr
    assert "integrating 101 members" in proc.stderr and "all succeeded" in proc.stderr
    table = read_csv(out)
    assert list(table)[:5] == ["g", "theta", "status", "t_reached", "final_theta"]
    g = table["g"]
    assert np.allclose(g, np.linspace(9.7, 9.9, 101), rtol=0, atol=1e-15) and np.all(table["theta"] == theta0)
    assert np.all(table["status"] == 0) and np.all(table["t_reached"] == t_end)
    omega = np.sqrt(g / 1.0)
    exact = exact_pendulum(theta0, omega, t_end)
    assert np.max(np.abs(table["final_theta"] - exact)) < 1e-8
    small = theta0 * np.cos(omega * t_end)
    # the frequency shift omega theta0^2 / 16 over t_end moves the phase by about 8e-4 rad here
    assert np.all(np.abs(table["final_theta"] - small) < 1.5 * theta0 * omega * t_end * theta0 ** 2 / 16)
    # energy is conserved member by member: E = -m g l cos(theta0) (m = l = 1)
    assert np.max(np.abs(table["final_energy"] + g * np.cos(theta0))) < 1e-9
    assert png.read_bytes()[:4] == b"\x89PNG" and png.stat().st_size > 5000


def test_grid_product_and_velocities(tmp_path):
    out = tmp_path / "p.npz"
    proc = run(PENDULUM, "--grid", "l=0.5,1,2", "--grid", "theta_dot=0:1:4", "-o", out, "--t-end", "1", "-q")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    data = np.load(out)
    assert list(data["columns"])[:3] == ["l", "theta_dot", "status"]
    assert len(data["l"]) == 12
    assert np.array_equal(data["l"], np.repeat([0.5, 1.0, 2.0], 4))          # the first --grid varies slowest
    assert np.allclose(data["theta_dot"], np.tile(np.linspace(0, 1, 4), 3))
    # E = l^2 theta_dot^2 / 2 - g l cos(theta0) with theta0 = 1 from the file, m = 1
    energy = data["l"] ** 2 * data["theta_dot"] ** 2 / 2 - 9.81 * data["l"] * np.cos(1.0)
    assert np.allclose(data["final_energy"], energy, rtol=1e-6, atol=0)       # the file's rtol is 1e-8


def test_sample_is_reproducible_with_a_seed(tmp_path):
    args = ["--sample", "l=uniform:0.9:1.1", "--sample", "theta=normal:1:0.1", "--n", "500", "--t-end", "2"]
    a, b, c = tmp_path / "a.npz", tmp_path / "b.npz", tmp_path / "c.npz"
    for path, seed in ((a, 1), (b, 1), (c, 2)):
        proc = run(PENDULUM, *args, "--seed", seed, "-o", path, "--plot", path.with_suffix(".png"),
                   "--plot-y", "energy")
        assert proc.returncode == 0, proc.stderr
        assert f"seed {seed}" in proc.stderr
    A, B, C = np.load(a), np.load(b), np.load(c)
    for key in A["columns"]:
        assert np.array_equal(A[key], B[key]), key      # same seed: the same members, the same results
    assert not np.array_equal(A["l"], C["l"])
    rng = np.random.default_rng(1)                       # the documented draw, in the order given
    assert np.array_equal(A["l"], rng.uniform(0.9, 1.1, 500))
    assert np.array_equal(A["theta"], rng.normal(1.0, 0.1, 500))
    assert np.all(A["status"] == 0)
    l, theta = A["l"], A["theta"]
    assert np.allclose(A["final_energy"], -9.81 * l * np.cos(theta), rtol=1e-6, atol=0)
    png = a.with_suffix(".png")
    assert png.read_bytes()[:4] == b"\x89PNG" and png.stat().st_size > 5000


def test_constrained_file_where_the_particle_leaves_the_sphere(tmp_path):
    """sliding_off_sphere.toml (index-1, terminal event on the normal force): the particle leaves
    where y/R = (2 + v0^2/(g R))/3; each member stops there (t_reached < t_end)."""
    out = tmp_path / "s.csv"
    proc = run(EXAMPLES / "sliding_off_sphere.toml", "--grid", "x_dot=0.01:1.5:7", "-o", out, "-q")
    assert proc.returncode == 0, proc.stderr
    table = read_csv(out)
    v0 = table["x_dot"]
    assert np.all(table["status"] == 0) and np.all(table["t_reached"] < 3.2)
    assert np.allclose(table["final_y"], (2 + v0 ** 2 / 9.81) / 3, rtol=0, atol=1e-7)
    assert np.max(np.abs(table["final_lambda_0"])) < 1e-7        # the normal force vanishes there


def test_constrained_ggl_members_are_data(tmp_path):
    """A sweep of x alone leaves the rod's constraint unsatisfied: every member is rejected (status
    -84) and the table is still written; with --project-initial they run, on the circle."""
    out = tmp_path / "c.csv"
    cart = EXAMPLES / "cartesian_pendulum.toml"
    proc = run(cart, "--grid", "x=0.3,0.6", "-o", out, "--formulation", "ggl", "--t-end", "1", "-q")
    assert proc.returncode == 4 and "rejected" in proc.stderr
    assert np.all(read_csv(out)["status"] == -84)
    proc = run(cart, "--grid", "x=0.3,0.6", "-o", out, "--formulation", "ggl", "--t-end", "1", "-q",
               "--project-initial")
    assert proc.returncode == 0, proc.stderr
    table = read_csv(out)
    assert np.all(table["status"] == 0)
    assert np.allclose(table["final_x"] ** 2 + table["final_y"] ** 2, 1.0, atol=1e-8)


BAD = [
    (["--grid", "g=9.7:9.9"], "START:STOP:NUM"),
    (["--grid", "g=9.7:9.9:1"], "at least 2"),
    (["--grid", "g=a:b:3"], "not a number"),
    (["--grid", "g=1:2:3", "--sample", "l=uniform:0:1", "--n", "3"], "exclude"),
    ([], "nothing to sweep"),
    (["--sample", "l=uniform:1:0", "--n", "3"], "LOW must be below HIGH"),
    (["--sample", "l=gamma:1:2", "--n", "3"], "DIST"),
    (["--sample", "l=uniform:0:1"], "--n"),
    (["--sample", "l=uniform:0:1", "--n", "0"], "--n 0"),
    (["--grid", "g=1:2:3", "--seed", "1"], "--sample only"),
    (["--grid", "g=1:2:3", "--grid", "g=1,2"], "swept twice"),
    (["--grid", "g=1:2:3", "--set", "g=1"], "both swept"),
    (["--grid", "g=1:2:3", "--threads", "0"], "--threads"),
    (["--grid", "g=1:2:3", "--rtol", "-1"], "--rtol"),
    (["--grid", "g=1:2:3", "--t-end", "nan"], "--t-end"),
    (["--grid", "g=1:2:3", "--plot", "x.pdf"], ".png"),
    (["--grid", "g=1:2:3", "--plot-y", "energy"], "needs --plot"),
    (["--grid", "zeta=1:2:3"], "cannot sweep 'zeta'"),
    (["--grid", "g=1:2:3", "--set", "zeta=1"], "--set zeta"),
    (["--grid", "g=1:2:3", "--formulation", "ggl"], "[constraints]"),
]


@pytest.mark.parametrize("extra,needle", BAD, ids=[" ".join(b[0]) or "empty" for b in BAD])
def test_bad_options_exit_2_before_any_work(tmp_path, capsys, extra, needle):
    out = tmp_path / "o.csv"
    assert main(["sweep", str(PENDULUM), "-o", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert needle in err and "compiled" not in err and "integrating" not in err, err
    assert not out.exists()


def test_bad_output_suffix_and_plot_y(tmp_path, capsys):
    assert main(["sweep", str(PENDULUM), "-o", str(tmp_path / "o.txt"), "--grid", "g=1:2:3"]) == 2
    assert ".csv or .npz" in capsys.readouterr().err
    # --plot-y is checked against the compiled outputs, before the integration
    out = tmp_path / "o.csv"
    assert main(["sweep", str(PENDULUM), "-o", str(out), "--grid", "g=1:2:3", "--plot", str(tmp_path / "p.png"),
                 "--plot-y", "nonsense", "-q"]) == 2
    err = capsys.readouterr().err
    assert "--plot-y nonsense" in err and "energy" in err and not out.exists()


def test_member_values_of_a_grid_and_a_sample():
    plan = check_options(SweepSpec("m.toml", "o.csv", grid=["a=0:1:3", "b=5,6"]))
    vals = member_values(plan)
    assert plan.n_members == 6
    assert np.array_equal(vals["a"], [0, 0, 0.5, 0.5, 1, 1]) and np.array_equal(vals["b"], [5, 6] * 3)
    plan = check_options(SweepSpec("m.toml", "o.npz", sample=["k=loguniform:1:100"], n=1000, seed=7))
    k = member_values(plan)["k"]
    assert k.min() >= 1 and k.max() <= 100 and 5 < np.median(k) < 20
    with pytest.raises(SweepOptionError):
        check_options(SweepSpec("m.toml", "o.csv", sample=["k=loguniform:0:1"], n=3))


def test_ctrl_c_exits_130_and_writes_nothing(tmp_path):
    out = tmp_path / "big.csv"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "lagcodegen", "sweep", str(PENDULUM), "--sample",
                             "g=uniform:9:10", "--n", "1000000", "--seed", "3", "-o", str(out), "--threads", "1",
                             "--t-end", "100"], stderr=subprocess.PIPE, text=True, env=env,
                            # pytest-xdist workers ignore SIGINT, and a Python started so never installs
                            # its handler: the default disposition back for the child
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        for line in proc.stderr:
            if "integrating" in line:
                break
        time.sleep(0.5)
        start = time.perf_counter()
        proc.send_signal(signal.SIGINT)
        _, rest = proc.communicate(timeout=30)
        rc = proc.returncode
    finally:
        if proc.poll() is None:
            proc.kill()
    assert rc == 130, rest
    assert time.perf_counter() - start < 5
    assert "nothing written" in rest and "interrupted" in rest
    assert not out.exists() and not list(tmp_path.iterdir())


def test_ctrl_c_while_plotting_leaves_neither_table_nor_plot(tmp_path, monkeypatch):
    import lagcodegen.sweep as sweep_module

    def interrupted(path, *args, **kwargs):
        Path(path).write_bytes(b"\x89PNG half")
        raise KeyboardInterrupt
    monkeypatch.setattr(sweep_module, "plot_sweep", interrupted)
    out = tmp_path / "out"
    assert main(["sweep", str(PENDULUM), "--grid", "g=9.7:9.9:3", "-o", str(out / "s.csv"), "--plot",
                 str(out / "s.png"), "--t-end", "0.5", "-q"]) == 130
    assert list(tmp_path.iterdir()) == []
