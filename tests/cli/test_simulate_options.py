"""`lagcodegen simulate`'s options for a newcomer: --initial, --plot-y, --plot-xy, --animate, negative
numbers given to numeric options, the model file's own initial state, and the energy message of
models that do not conserve energy."""

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import lagcodegen as lcg
from lagcodegen.animation import ffmpeg_available
from lagcodegen.cli import main
from lagcodegen.cli.simulate import column_figure, not_conserved
from lagcodegen.result import Result

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
PENDULUM = EXAMPLES / "pendulum.toml"  # l = 1, g = 9.81, m = 1; initial theta = 1 at rest


def simulate(*args) -> int:
    return main(["simulate", *map(str, args)])


def rows(path: Path) -> tuple[list[str], np.ndarray]:
    header = path.read_text().splitlines()[0].split(",")
    return header, np.loadtxt(path, delimiter=",", skiprows=1)


def test_without_initial_the_file_s_initial_state_is_used(tmp_path):
    assert simulate(PENDULUM, "-o", tmp_path / "p.csv", "--t-end", "1", "-q") == 0
    header, data = rows(tmp_path / "p.csv")
    assert data[0, header.index("theta")] == 1.0 and data[0, header.index("theta_dot")] == 0.0


def test_initial_replaces_the_named_values(tmp_path):
    out = tmp_path / "p.csv"
    assert simulate(PENDULUM, "-o", out, "--t-end", "2", "--initial", "theta=2.5", "--rtol", "1e-10",
                    "--atol", "1e-12", "-q") == 0
    header, data = rows(out)
    assert data[0, header.index("theta")] == 2.5 and data[0, header.index("theta_dot")] == 0.0
    # released at rest: E = -m g l cos(theta0), independent of the solver
    assert data[0, header.index("energy")] == pytest.approx(-9.81 * np.cos(2.5), rel=1e-14)
    # the same run from Python
    ref = lcg.compile_model(lcg.systems.pendulum()).simulate(data[:, 0], q0=[2.5], rtol=1e-10, atol=1e-12)
    assert np.max(np.abs(data[:, header.index("theta")] - ref["theta"])) < 1e-7
    # velocities by <q>_dot; a second --initial adds to the first; negative values in exponent form
    assert simulate(PENDULUM, "-o", out, "--t-end", "1", "--initial", "theta=-2e-1", "--initial",
                    "theta_dot=0.5", "-q") == 0
    header, data = rows(out)
    assert data[0, header.index("theta")] == -0.2 and data[0, header.index("theta_dot")] == 0.5


@pytest.mark.parametrize("value, message", [
    ("thetaa=2.5", "--initial 'thetaa': not a coordinate or velocity of pendulum; did you mean 'theta'?"),
    ("theta", "--initial expects NAME=VALUE pairs"),
    ("theta=abc", "--initial theta: 'abc' is not a number"),
    ("theta=inf", "--initial theta: give a finite number"),
])
def test_bad_initial_values_are_named(tmp_path, capsys, value, message):
    assert simulate(PENDULUM, "-o", tmp_path / "p.csv", "--initial", value, "-q") == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "p.csv").exists()


@pytest.mark.parametrize("option, value, message", [
    ("--rtol", "-1e-6", "--rtol -1e-06: give a finite non-negative number"),
    ("--atol", "-1E-12", "--atol -1e-12: give a finite non-negative number"),
    ("--t-end", "-inf", "--t-end -inf: give a finite positive number"),
    ("--t-end", "-2", "--t-end -2.0: give a finite positive number"),
])
def test_negative_numbers_get_the_option_s_own_message(tmp_path, capsys, option, value, message):
    assert simulate(PENDULUM, "-o", tmp_path / "p.csv", option, value) == 2
    err = capsys.readouterr().err
    assert message in err and "expected one argument" not in err


def test_a_negative_parameter_value_in_exponent_form_is_taken(tmp_path):
    out = tmp_path / "p.csv"
    assert simulate(PENDULUM, "-o", out, "--t-end", "0.5", "--set", "g=-9.81e0", "-q") == 0
    header, data = rows(out)
    assert data[0, header.index("energy")] == pytest.approx(9.81 * np.cos(1.0), rel=1e-14)  # -m g l cos(theta)


def test_plot_y_chooses_the_panels(tmp_path, monkeypatch):
    drawn = []
    real = Result.plot
    monkeypatch.setattr(Result, "plot", lambda self, path=None, what=None, **kw: drawn.append((what, kw))
                        or real(self, path, what, **kw))
    png = tmp_path / "p.png"
    assert simulate(PENDULUM, "-o", tmp_path / "p.csv", "--t-end", "1", "--plot", png,
                    "--plot-y", "theta+theta_dot,energy", "-q") == 0
    assert drawn == [([["theta", "theta_dot"], ["energy"]], {})]
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_plot_xy_draws_one_column_against_another(tmp_path):
    orbit = EXAMPLES / "central_potential.toml"
    png = tmp_path / "orbit.png"
    assert simulate(orbit, "-o", tmp_path / "o.csv", "--plot", png, "--plot-xy", "body_x,body_y", "-q") == 0
    assert png.read_bytes()[:4] == b"\x89PNG"
    header, data = rows(tmp_path / "o.csv")
    res = Result(data[:, 0], data[:, 1:5], header[1:5], {k: data[:, header.index(k)] for k in ("body_x", "body_y")})
    fig = column_figure(res, "body_x", "body_y")
    line = fig.axes[0].lines[0]
    assert np.array_equal(line.get_xdata(), data[:, header.index("body_x")])
    assert np.array_equal(line.get_ydata(), data[:, header.index("body_y")])
    assert fig.axes[0].get_aspect() == 1.0  # a path in true proportions
    # a point's name: its path, from the model
    assert simulate(orbit, "-o", tmp_path / "o.csv", "--plot", png, "--plot-xy", "body", "-q") == 0


@pytest.mark.parametrize("options, message", [
    (["--plot-y", "theta"], "--plot-y chooses what --plot draws: give --plot FILE.png too"),
    (["--plot", "p.png", "--plot-y", "theta", "--plot-xy", "bob_x,bob_y"], "not both"),
    (["--plot", "p.png", "--plot-xy", "a,b,c"], "give two column names X,Y or one point's name"),
    (["--plot", "p.png", "--plot-y", "enrgy"], "--plot-y 'enrgy': not a column of the result; did you mean 'energy'?"),
    (["--plot", "p.png", "--plot-xy", "bob_x,bob_z"], "--plot-xy 'bob_z': not a column of the result"),
    (["--animate", "p.avi"], "--animate 'p.avi': give a file ending in .gif, .mp4, .html"),
])
def test_plot_and_animation_options_are_checked_before_writing(tmp_path, capsys, monkeypatch, options, message):
    monkeypatch.chdir(tmp_path)
    assert simulate(PENDULUM, "-o", "p.csv", *options, "-q") == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_animate_writes_the_mechanism_moving(tmp_path):
    gif = tmp_path / "pendulum.gif"
    assert simulate(PENDULUM, "-o", tmp_path / "p.csv", "--t-end", "2", "--animate", gif, "-q") == 0
    assert Image.open(gif).n_frames > 10
    html = tmp_path / "cp.html"
    assert simulate(EXAMPLES / "cartesian_pendulum.toml", "-o", tmp_path / "cp.csv", "--t-end", "1",
                    "--animate", html, "-q") == 0  # a constrained model, drawn with its rod
    assert "<html" in html.read_text().lower() or "animation" in html.read_text().lower()


def test_mp4_without_ffmpeg_is_refused_before_any_work(tmp_path, capsys):
    code = simulate(PENDULUM, "-o", tmp_path / "p.csv", "--t-end", "1", "--animate", tmp_path / "p.mp4", "-q")
    if ffmpeg_available():
        assert code == 0 and (tmp_path / "p.mp4").stat().st_size > 0
    else:
        assert code == 2 and "an MP4 needs ffmpeg" in capsys.readouterr().err
        assert not (tmp_path / "p.csv").exists()


def test_energy_message_says_drift_only_where_energy_is_conserved(tmp_path, capsys):
    assert simulate(PENDULUM, "-o", tmp_path / "p.csv", "--t-end", "2") == 0
    err = capsys.readouterr().err
    assert "energy drift over the run" in err
    assert simulate(EXAMPLES / "damped_driven_oscillator.toml", "-o", tmp_path / "d.csv") == 0
    err = capsys.readouterr().err
    assert "energy drift" not in err
    assert "energy changed over the run by" in err and "as it may: the model has dissipation" in err


MODEL = """
[model]
name = "m"
coordinates = ["x", "y"]
[parameters]
w = 2.0
[[particles]]
name = "p"
mass = 1.0
position = ["x", "y"]
"""


@pytest.mark.parametrize("extra, reason", [
    ("[energy]\npotential = \"x**2 + y**2\"\n", None),
    ("[[dampers]]\npoint = \"p\"\nc = 0.1\n", "dissipation"),
    ("[[forces]]\npoint = \"p\"\nvector = [\"1\", \"0\"]\n", "applied forces"),
    ("[energy]\npotential = \"cos(w*t)*x**2\"\n", "a Lagrangian that depends on time"),
    ("[constraints]\nholonomic = [\"x**2 + y**2 - 1\"]\n", None),
    ("[constraints]\nholonomic = [\"x - sin(w*t)\"]\n", "constraints that depend on time"),
])
def test_which_models_conserve_their_energy(tmp_path, extra, reason):
    path = tmp_path / "m.toml"
    path.write_text(MODEL + extra)
    assert not_conserved(lcg.modelfile.load_model_path(path)) == reason


def test_help_texts_speak_to_users(capsys):
    for argv in (["--help"], ["simulate", "--help"], ["generate", "--help"], ["info", "--help"],
                 ["sweep", "--help"]):
        with pytest.raises(SystemExit):
            main(argv)
        text = capsys.readouterr().out
        assert "One job" not in text and len(text) > 500
    with pytest.raises(SystemExit):
        main(["info", "--help"])
    text = capsys.readouterr().out
    assert "Lagrange's equations" in text and "(eq. 3.16)" in text and "generalized momenta" in text
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for flag in ("--initial", "--animate", "--plot-y", "--plot-xy"):
        assert flag in text
