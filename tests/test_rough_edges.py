"""The robustness findings of a newcomer's first hour (issue 27), each a clear error or a correct
result: huge powers and numbers beyond double range refused before any C is written, outputs
named like a state refused, the ensembles' progress bar one line every few seconds in a log,
the constrained functions given empty arrays."""

import io
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen import ModelError, fitting, progress
from lagcodegen.modelfile import ModelFileError, loads_model
from lagcodegen.modelfile.expressions import MAX_POWER
from lagcodegen.solvers import control

ROOT = Path(__file__).resolve().parents[1]

PENDULUM = """
[model]
name = "p"
coordinates = ["theta"]
[parameters]
g = 9.81
[[particles]]
name = "bob"
mass = 1
position = ["{x}", "-cos(theta)"]
[energy]
potential = "{v}"
"""


def pendulum_file(x="sin(theta)", v="g*theta", extra=""):
    return PENDULUM.format(x=x, v=v) + extra


# ---------------------------------------------------------------------- powers and number range
def test_a_huge_power_is_refused_at_load_naming_it():
    t0 = time.perf_counter()
    with pytest.raises(ModelFileError) as err:
        loads_model(pendulum_file(x="(theta + 1)**100000"))
    assert time.perf_counter() - t0 < 30  # unbounded before (derivation ran for minutes)
    msg = str(err.value)
    assert "particles[0].position[0]" in msg and "(theta + 1)**100000" in msg and str(MAX_POWER) in msg
    # powers built in steps are seen too; the bound itself is allowed
    for text in ("((theta+1)**20)**20", "(theta+1)**60*(1+theta)**60"):
        with pytest.raises(ModelFileError, match="limited to"):
            loads_model(pendulum_file(x=text))
    mf = loads_model(pendulum_file(x=f"(theta + 1)**{MAX_POWER}"))
    assert mf.model.points["bob"].position[0] == (sp.Symbol("theta") + 1) ** MAX_POWER
    assert loads_model(pendulum_file(v="g*theta**-3 + (1 + theta)**2")).model is not None


def test_a_number_beyond_double_range_is_refused_at_load():
    with pytest.raises(ModelFileError) as err:
        loads_model(pendulum_file(v="(1e200*theta)**2"))
    assert "energy.potential" in str(err.value) and "double precision" in str(err.value)


def test_coefficients_beyond_double_range_in_the_equations_are_refused_before_any_c():
    mf = loads_model(pendulum_file(x="1e200*theta"))  # fine alone; squared in T: 1e400 in M
    with pytest.raises(ModelError) as err:
        lcg.generate_code(lcg.Scene(lcg.derive(mf.model)), "c")
    assert "M[0][0]" in str(err.value) and "double precision" in str(err.value)
    # the Python API the same; a large but representable scale is fine and its C has no inf
    m = lcg.Model("big")
    th, = m.coordinates("theta")
    m.particle("b", 1, (sp.Float(1e200) * th, 0))
    with pytest.raises(ModelError, match="beyond double precision"):
        lcg.Scene(lcg.derive(m))
    ok = loads_model(pendulum_file(x="1e100*theta"))
    code = lcg.generate_code(lcg.Scene(lcg.derive(ok.model)), "c")
    assert not any("inf" in line.split("//")[0] for text in code.files.values() for line in text.splitlines()
                   if "=" in line and "info" not in line)


# ---------------------------------------------------------------------- outputs named like states
def test_an_output_named_like_a_state_is_refused():
    with pytest.raises(ModelFileError) as err:
        loads_model(pendulum_file(extra='[outputs]\ntheta = "100*theta"\n'))
    msg = str(err.value)
    assert ":14:" in msg and "outputs.theta" in msg and "name of a state" in msg
    with pytest.raises(ModelFileError, match="name of a state"):
        loads_model(pendulum_file(extra='[outputs]\ntheta_dot = "2*theta_dot"\n'))
    m = lcg.systems.pendulum()
    th = m.coords[0]
    m.output("theta_dot", 100 * th)
    with pytest.raises(ModelError, match="velocity of coordinate 'theta'"):
        lcg.Scene(lcg.derive(m), outputs=["theta_dot"])
    m.output("scaled", 100 * th)  # another name works, and is the expression asked for
    sim = lcg.compile_model(m, outputs=["scaled"])
    res = sim.simulate([0, 1], q0=[0.3])
    assert abs(res["scaled"][-1] - 100 * res["theta"][-1]) < 1e-9


# ---------------------------------------------------------------------- progress into a log
class Clock:
    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


class FakeTerminal(io.StringIO):
    def isatty(self):
        return True


def test_ensemble_progress_into_a_log_is_a_line_every_few_seconds(monkeypatch):
    clock = Clock()
    monkeypatch.setattr(time, "perf_counter", clock)
    log = io.StringIO()
    bar = control.Progress(100, show=None, after=2.0, stream=log)
    for done in range(100):  # the poll callback: every 0.05 s, for 5 s
        clock.now += control.POLL_EVERY
        bar.update(done, 100)
    bar.close(100)
    text = log.getvalue()
    assert "\r" not in text
    lines = text.splitlines()
    # shown from 2 s on: at 2 s, then every LOG_EVERY seconds, plus the final count
    assert 2 <= len(lines) <= 3, lines
    assert lines[-1].startswith("ensemble [") and "100/100" in lines[-1]


def test_ensemble_progress_on_a_terminal_redraws_in_place_at_most_every_refresh(monkeypatch):
    clock = Clock()
    monkeypatch.setattr(time, "perf_counter", clock)
    tty = FakeTerminal()
    bar = control.Progress(100, show=True, stream=tty)
    for done in range(100):
        clock.now += control.POLL_EVERY
        bar.update(done, 100)
    bar.close(100)
    text = tty.getvalue()
    draws = text.count("\r")
    most = 100 * control.POLL_EVERY / progress.REFRESH + 2  # 5 s of polls: 25 redraws at most, not 100
    assert most / 2 <= draws <= most
    assert text.endswith("\n") and text.count("\n") == 1 and "100/100" in text.rsplit("\r", 1)[-1]


def test_status_line_draws_nothing_when_nothing_was_written():
    log = io.StringIO()
    line = progress.StatusLine(log)
    line.close()
    assert log.getvalue() == ""


# ---------------------------------------------------------------------- constrained functions, empty arrays
def test_constrained_functions_given_empty_arrays_raise_instead_of_crashing(tmp_path):
    """Run in a child process: a segmentation fault would end it (exit code < 0), not fail here."""
    script = textwrap.dedent("""
        import numpy as np
        from helpers import cartesian_pendulum
        from lagcodegen.api import compile_constrained
        from lagcodegen.errors import LagcodegenError
        sim = compile_constrained(cartesian_pendulum("cpempty"), "index1")
        y = np.array([0.6, -0.8, 0.0, 0.0])
        calls = {"kkt": lambda a: sim.kkt(0.0, a), "residuals": lambda a: sim.residuals(0.0, a),
                 "project": lambda a: sim.project(0.0, a), "outputs": lambda a: sim.outputs(0.0, a),
                 "kkt params": lambda a: sim.kkt(0.0, y, a), "project params": lambda a: sim.project(0.0, y, a),
                 "outputs lam": lambda a: sim.outputs(0.0, y, lam=a)}
        for name, call in calls.items():
            for empty in (np.array([]), [], np.zeros((0, 4))):
                try:
                    call(empty)
                except LagcodegenError as exc:
                    assert "values, expected" in str(exc), exc
                else:
                    raise SystemExit(f"{name}: no error")
        print("ok")
    """)
    env = {"PYTHONPATH": f"{ROOT}:{ROOT / 'tests'}", "PATH": "/usr/bin:/bin"}
    import os
    env = {**os.environ, **env}
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, (proc.returncode, proc.stderr[-2000:])
    assert proc.stdout.strip() == "ok"


# ---------------------------------------------------------------------- look-alike names (NFKC)
def test_a_look_alike_name_in_an_expression_is_refused_naming_the_character_file_and_line():
    """Python reads the full-width 'ｋ' as 'k' (NFKC): it silently became the parameter k."""
    text = pendulum_file(v="ｋ*theta**2", extra="").replace("g = 9.81", "g = 9.81\nk = 1.0")
    with pytest.raises(ModelFileError) as err:
        loads_model(text, "lookalike.toml")
    msg = str(err.value)
    assert msg.startswith("lookalike.toml:13:") and "energy.potential" in msg
    assert "'ｋ'" in msg and "U+FF4B" in msg and "FULLWIDTH LATIN SMALL LETTER K" in msg and "'k'" in msg
    with pytest.raises(ModelFileError, match=r"U\+2113 SCRIPT SMALL L"):  # was "unknown name 'l'"
        loads_model(pendulum_file(v="ℓ*theta"), "lookalike.toml")
    with pytest.raises(ModelFileError, match="U\\+FF53"):  # a function name too
        loads_model(pendulum_file(x="ｓin(theta)"), "lookalike.toml")
    assert loads_model(pendulum_file(v="g*theta")).model is not None


def test_a_look_alike_name_cannot_be_declared():
    text = pendulum_file(v="k*theta**2").replace("g = 9.81", 'g = 9.81\nk = 1.0\n"ｋ" = 5.0')
    with pytest.raises(ModelFileError) as err:
        loads_model(text, "lookalike.toml")
    assert str(err.value).startswith("lookalike.toml:8:") and "U+FF4B" in str(err.value)
    m = lcg.Model("m")
    with pytest.raises(ModelError, match="coordinate name 'ℓ'.*U\\+2113"):
        m.coordinates("ℓ")
    assert m.coordinates("θ")  # a name Python keeps as written is fine


# ---------------------------------------------------------------------- what compile_model / compile_file take
def test_compile_model_given_a_path_or_none_says_what_it_takes():
    """Was AttributeError: 'str' object has no attribute 'n'."""
    for bad in ("pendulum.toml", ROOT / "examples" / "pendulum.toml"):
        with pytest.raises(ModelError) as err:
            lcg.compile_model(bad)
        msg = str(err.value)
        assert "compile_model takes a Model" in msg and "pendulum.toml" in msg and "compile_file(path)" in msg
        assert "load_model_path" in msg
    with pytest.raises(ModelError, match="compile_model takes a Model .*got None"):
        lcg.compile_model(None)
    with pytest.raises(ModelError, match=r"got a ModelFile .*compile_file\(mf\)"):
        lcg.compile_model(lcg.modelfile.load_model(ROOT / "examples" / "pendulum.toml"))
    with pytest.raises(ModelError, match="derive takes a Model"):
        lcg.derive("pendulum.toml")


def test_compile_file_loads_a_path_and_says_what_it_takes():
    cm = lcg.compile_file(str(ROOT / "examples" / "pendulum.toml"))  # was: 'str' object has no attribute 'simulation'
    assert cm.state_names == ["theta", "theta_dot"]
    with pytest.raises(ModelError, match=r"compile_file takes a loaded model file .*got a Model: .*compile_model"):
        lcg.compile_file(lcg.systems.pendulum())
    with pytest.raises(ModelError, match="compile_file takes .*got None"):
        lcg.compile_file(None)


# ---------------------------------------------------------------------- empty ensembles, deep TOML, animation sizes
def test_an_ensemble_of_no_members_is_a_clear_error():
    import numpy as np
    sim = lcg.compile_model(lcg.systems.pendulum())
    for kw in (dict(q0=np.zeros((0, 1))), dict(q0=[0.1], params=np.zeros((0, 3))), dict(q0=[0.1], params={"g": []}),
               dict(q0={"theta": []})):
        with pytest.raises(lcg.LagcodegenError, match="the ensemble has no members"):  # was a bare IndexError
            sim.ensemble([0, 1], **kw)


def test_deeply_nested_toml_is_a_clear_error_naming_the_file(tmp_path):
    path = tmp_path / "deep.toml"
    path.write_text('[model]\nname = "p"\ncoordinates = ["x"]\n[simulation]\ninitial = '
                    + "[" * 100_000 + "]" * 100_000 + "\n")
    with pytest.raises(ModelFileError) as err:  # was a bare RecursionError
        lcg.modelfile.load_model(path)
    assert str(err.value).startswith(f"{path}:") and "nested too deeply" in str(err.value)


def test_animation_size_and_dpi_are_checked_and_named(tmp_path):
    res = lcg.compile_model(lcg.systems.pendulum()).simulate([0, 0.2], q0=[0.5])
    out = tmp_path / "a.gif"
    # were ZeroDivisionError, IndexError and ValueError from matplotlib
    for kw, word in ((dict(dpi=0), "dpi"), (dict(dpi=-80), "dpi"), (dict(dpi=float("nan")), "dpi"),
                     (dict(size=(float("nan"), 5)), "size"), (dict(size=5), "size"), (dict(size=(5, -1)), "size"),
                     (dict(dpi=0.1), "pixels"), (dict(size=(5, 1e6)), "pixels")):
        with pytest.raises(lcg.LagcodegenError, match=word):
            res.animate(out, frames=2, **kw)
    assert not out.exists()
    assert res.animate(out, frames=2, dpi=40, size=(3, 2)) == out and out.stat().st_size > 0


# ---------------------------------------------------------------------- messages show excerpts of inputs
def test_messages_show_a_bounded_excerpt_of_a_huge_input():
    """The README promises about 80 characters of an offending input; these echoed it whole."""
    import warnings
    big = "9" * 5000
    base = '[model]\nname = "p"\ncoordinates = ["theta"]\n[[particles]]\nname = "bob"\nmass = MASS\n' \
           'position = ["sin(theta)", "-cos(theta)"]\n'
    for mass, expect in ((big, "too large to read"), (f'"-{big}*theta"', "number too large")):
        with pytest.raises(ModelFileError) as err:  # the bare literal: a ValueError from tomllib before
            loads_model(base.replace("MASS", mass), "m.toml")
        msg = str(err.value)
        assert msg.startswith("m.toml:6:") and expect in msg and len(msg) < 300, msg
    m = lcg.Model("p")
    th, = m.coordinates("theta")
    with pytest.warns(UserWarning) as caught:
        m.particle("neg", -sp.Integer(10) ** 5000, (sp.sin(th), 0))
    assert "is negative" in str(caught[0].message) and len(str(caught[0].message)) < 300
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for mass, position in (("x" * 5000, (th, 0)), (1, 7 ** 900)):
            with pytest.raises(ModelError) as err:
                m.particle("b", mass, position)
            assert len(str(err.value)) < 300, str(err.value)[:400]
    # constraints: a long holonomic constraint without a coordinate, a long inequality violated at the start
    cm = lcg.Model("c")
    x, y = cm.coordinates("x y")
    cm.particle("b", 1, (x, y))
    long = sum(sp.Symbol("t") ** k / (k + 1) for k in range(150))
    with pytest.raises(ModelError) as err:
        lcg.ConstrainedSystem(cm, holonomic=[long])
    assert "involves no coordinate" in str(err.value) and len(str(err.value)) < 300
    system = lcg.ConstrainedSystem(cm, inequalities=[y - 10 - sum(x ** k / (k + 1) for k in range(2, 150))])
    with pytest.raises(ModelError) as err:
        system.check_initial([0.0, 0.0])
    assert "is violated" in str(err.value) and len(str(err.value)) < 400
    with pytest.raises(ModelError) as err:
        lcg.compile_constrained(system, "index1" * 900)
    assert "formulation must be one of" in str(err.value) and len(str(err.value)) < 300


def test_a_sympy_system_with_long_constraints_is_refused_in_a_bounded_message():
    me = pytest.importorskip("sympy.physics.mechanics")
    q1, q2 = me.dynamicsymbols("q1 q2")
    ground = me.RigidBody("ground")
    bob = me.Particle("bob", mass=sp.Symbol("m"))
    system = me.System.from_newtonian(ground)
    joint = me.PinJoint("j", ground, bob, coordinates=q1, speeds=q1.diff(me.dynamicsymbols._t),
                        joint_axis=ground.frame.z, child_point=bob.masscenter)
    system.add_joints(joint)
    system.add_coordinates(q2)
    system.add_speeds(q2.diff(me.dynamicsymbols._t))
    system.add_holonomic_constraints(q1 - sum(q2 ** k / (k + 1) for k in range(1, 120)))
    with pytest.raises(ModelError) as err:
        lcg.derive(system)
    msg = str(err.value)
    assert "the System has holonomic constraints" in msg and "characters)" in msg and len(msg) < 500, msg[:600]
# ---------------------------------------------------------------------- fits: convergence, duplicated columns
def cli(*args, cwd=None):
    import os
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "lagcodegen", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=600)


def write_csv(path, header, t, *cols):
    import numpy as np
    rows = np.column_stack([t, *cols])
    path.write_text(",".join(header) + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n")
    return path


def test_a_fit_that_cannot_converge_says_so_and_exits_6(tmp_path):
    """Data no pendulum reaches (theta = 1e9): the optimizer stops on ftol at a cost of 1e19
    with the gradient far from zero; before, exit 0 and no word of it."""
    import numpy as np
    t = np.linspace(0.0, 5.0, 21)
    data = write_csv(tmp_path / "far.csv", ["t", "theta"], t, np.full(t.size, 1e9))
    proc = cli("fit", ROOT / "examples" / "pendulum.toml", data, "--fit", "l", "-o", tmp_path / "fit.csv")
    assert proc.returncode == 6, (proc.returncode, proc.stderr)
    assert "fit not converged" in proc.stderr and "l = " in proc.stdout
    assert (tmp_path / "fit.csv").exists()  # the estimates are still written
    assert "6  fit: the fit did not converge" in cli("--help").stdout
    assert "exits with code 6" in cli("fit", "--help").stdout
    # the Python API: converged False, and said in its summary; a good fit is converged
    sim = lcg.compile_model(lcg.systems.pendulum())
    far = fitting.fit(sim, t, np.full(t.size, 1e9), params={"l": 1.0}, observe=["theta"], q0=[1.0])
    assert far.success and not far.converged and far.stationarity > fitting.STATIONARITY
    assert "not converged" in str(far)
    theta = sim.simulate(t, q0=[1.0], params={"l": 1.3})["theta"]
    good = fitting.fit(sim, t, theta, params={"l": 1.0}, observe=["theta"], q0=[1.0])
    assert good.converged and abs(good.params["l"] - 1.3) < 1e-6 and "not converged" not in str(good)
    # a minimum on a bound is one: the gradient there points out of the range
    bounded = fitting.fit(sim, t, theta, params={"l": 1.0}, observe=["theta"], q0=[1.0], bounds={"l": (0.5, 1.1)})
    assert bounded.converged and bounded.params["l"] == pytest.approx(1.1)


def test_a_duplicated_data_column_is_refused(tmp_path):
    """The same column twice counted every measurement twice: the standard errors shrank by sqrt 2."""
    import numpy as np
    t = np.linspace(0.0, 5.0, 21)
    sim = lcg.compile_model(lcg.systems.pendulum())
    theta = sim.simulate(t, q0=[1.0], params={"l": 1.3})["theta"]
    data = write_csv(tmp_path / "dup.csv", ["t", "theta", "theta"], t, theta, theta)
    proc = cli("fit", ROOT / "examples" / "pendulum.toml", data, "--fit", "l")
    assert proc.returncode == 1 and "'theta' appears more than once" in proc.stderr, proc.stderr
    once = write_csv(tmp_path / "once.csv", ["t", "theta"], t, theta)
    proc = cli("fit", ROOT / "examples" / "pendulum.toml", once, "--fit", "l", "--observe", "theta,theta")
    assert proc.returncode == 2 and "theta given more than once" in proc.stderr, proc.stderr
    with pytest.raises(lcg.LagcodegenError, match="'theta' observed more than once"):
        fitting.fit(sim, t, np.column_stack([theta, theta]), params={"l": 1.0}, observe=["theta", "theta"],
                        q0=[1.0])


def test_an_input_given_a_value_and_a_table_is_refused_naming_it():
    """Before, the table silently won over params={"F": ...}."""
    import numpy as np
    sim = lcg.compile_model(lcg.systems.forced_oscillator("osc_both", m=1.0, k=4.0, c=0.4))
    t = np.linspace(0.0, 1.0, 11)
    table = lcg.Table([0.0, 1.0], [0.0, 2.0])
    with pytest.raises(lcg.LagcodegenError, match="'F' given both a value \\(params=\\) and a table"):
        sim.simulate(t, q0=[0.0], params={"F": 3.0}, inputs={"F": table})
    with pytest.raises(lcg.LagcodegenError, match="'F' given both"):
        sim.ensemble(t, q0=np.zeros((2, 1)), params={"F": [1.0, 2.0]}, inputs={"F": table})
    assert sim.simulate(t, q0=[0.0], params={"k": 9.0}, inputs={"F": table}).success


# ---------------------------------------------------------------------- paths that cannot be written
def test_fmu_and_output_paths_that_cannot_be_written_say_why(tmp_path, capsys):
    """--fmu at a folder wrote FOLDER/out.fmu silently; a file where a folder should be gave a
    bare "[Errno 17] File exists"."""
    folder = tmp_path / "existing_dir"
    folder.mkdir()
    afile = tmp_path / "afile"
    afile.write_text("")
    from lagcodegen.cli import main
    pendulum = str(ROOT / "examples" / "pendulum.toml")
    cases = [(["--fmu", str(folder)], f"{folder} is a folder; give the FMU's file name, ending in .fmu"),
             (["--fmu", str(afile / "x.fmu")], f"{afile} is a file, not a folder"),
             (["-o", str(afile)], f"-o {afile}: {afile} is a file, not a folder"),
             (["-o", str(afile / "sub")], f"{afile} is a file, not a folder")]
    for extra, message in cases:
        capsys.readouterr()
        assert main(["generate", pendulum, *extra, "-q"]) == 2, extra
        err = capsys.readouterr().err
        assert message in err and "Errno" not in err, (extra, err)
    # the result files of the other commands the same, before any work
    for command in (["simulate", pendulum, "-o", str(afile / "r.csv")],
                    ["simulate", pendulum, "-o", str(tmp_path / "r.csv"), "--plot", str(afile / "r.png")],
                    ["sweep", pendulum, "--grid", "g=9.7:9.9:3", "-o", str(afile / "g.csv")]):
        capsys.readouterr()
        assert main([*command, "-q"]) == 2, command
        err = capsys.readouterr().err
        assert f"{afile} is a file, not a folder" in err and "Errno" not in err, (command, err)
    assert list(folder.iterdir()) == []
    with pytest.raises(lcg.LagcodegenError, match="is a folder; give the FMU's file name"):
        lcg.export_fmu(ROOT / "examples" / "pendulum.toml", folder)
    with pytest.raises(lcg.LagcodegenError, match="afile is a file, not a folder"):
        lcg.write_bundle(lcg.Scene(lcg.derive(lcg.systems.pendulum())), afile / "b")


# ---------------------------------------------------------------------- particles on a line
SPRING_1D = """
[model]
name = "line_spring"
coordinates = ["x"]
[parameters]
m = 2.0
k = 8.0
[[particles]]
name = "mass"
mass = "m"
position = ["x"]
[energy]
potential = "k*x**2/2"
[simulation]
t_end = 3.0
initial = { x = 0.5, x_dot = 0.3 }
"""


def test_a_particle_on_a_line_is_the_analytic_harmonic_oscillator():
    """position = ["x"] and Model.particle(name, m, (x,)) were refused ("must have 2 or 3
    components"); now T = m x'^2/2, and with a spring x = x0 cos(w t) + v0/w sin(w t), w = sqrt(k/m)."""
    import numpy as np
    t = np.linspace(0.0, 3.0, 61)
    w = 2.0  # sqrt(8 / 2)
    exact = 0.5 * np.cos(w * t) + 0.3 / w * np.sin(w * t)
    mf = loads_model(SPRING_1D)
    assert mf.model.points["mass"].dim == 1
    res = lcg.compile_file(mf).simulate(t, q0=[0.5], v0=[0.3], rtol=1e-11, atol=1e-13)
    assert np.max(np.abs(res["x"] - exact)) < 1e-8
    m = lcg.Model("line_spring_py")
    x, = m.coordinates("x")
    mass, k = m.parameters(m=2.0, k=8.0)
    m.particle("p", mass, (x,))
    m.spring("p", (0,), k)
    eom = lcg.derive(m)
    assert sp.simplify(eom.T - mass * eom.qd[0] ** 2 / 2) == 0 and eom.M == sp.Matrix([[mass]])
    res = lcg.compile_model(m, outputs=["positions"]).simulate(t, q0=[0.5], v0=[0.3], rtol=1e-11, atol=1e-13)
    assert np.max(np.abs(res["x"] - exact)) < 1e-8 and np.allclose(res["p_x"], res["x"])
    # gravity along the line only with an explicit one-component up: the equilibrium moves to -m g / k
    m.gravity(9.81, up=(1,))
    res = lcg.compile_model(m).simulate(t, q0=[0.5], rtol=1e-11, atol=1e-13)
    shift = -2.0 * 9.81 / 8.0
    assert np.max(np.abs(res["x"] - (shift + (0.5 - shift) * np.cos(w * t)))) < 1e-8


def test_gravity_on_a_particle_on_a_line_without_a_direction_is_refused_clearly():
    with pytest.raises(ModelFileError) as err:
        loads_model(SPRING_1D + '[gravity]\ng = 9.81\n')
    msg = str(err.value)
    assert "gravity on 'mass', a particle on a line" in msg and "up = [1]" in msg
    ok = loads_model(SPRING_1D + '[gravity]\ng = 9.81\nup = [-1]\n')
    assert ok.model.gravity_spec[1] == sp.Matrix([-1])
    with pytest.raises(ModelFileError, match="'up' has 2 components, 'mass' has 1"):
        loads_model(SPRING_1D + '[gravity]\ng = 9.81\nup = [0, 1]\n')
    m = lcg.Model("line_gravity")
    x, = m.coordinates("x")
    m.particle("p", 1, (x,))
    m.gravity(9.81)
    with pytest.raises(ModelError, match="a particle on a line"):
        lcg.derive(m)
    with pytest.raises(ModelError, match="must have 1, 2 or 3 components, got 4"):
        m.particle("q", 1, (x, x, x, x))


# ---------------------------------------------------------------------- a model file's initial state
@pytest.mark.parametrize("name, formulation", [("double_pendulum", None), ("cartesian_pendulum", "index1"),
                                               ("cartesian_pendulum", "minimal")])
def test_compile_file_simulate_starts_from_the_files_initial_state(tmp_path, name, formulation):
    """compile_file(mf).simulate(t) without q0 started from zeros (the constrained ones refused:
    "q0 is required"); now from [simulation] initial, as the command line does."""
    import numpy as np
    from lagcodegen.modelfile import load_model
    from lagcodegen.modelfile.document import constrained_method
    path = ROOT / "examples" / f"{name}.toml"
    mf = load_model(path)
    s = mf.simulation
    extra = ["--formulation", formulation] if formulation else []
    proc = cli("simulate", path, "-o", tmp_path / "out.csv", "-q", *extra)
    assert proc.returncode == 0, proc.stderr
    header = (tmp_path / "out.csv").read_text().splitlines()[0].split(",")
    table = np.loadtxt(tmp_path / "out.csv", delimiter=",", skiprows=1)
    sim = lcg.compile_file(mf, **({"formulation": formulation} if formulation else {}))
    q0, v0 = mf.initial_state()
    assert any(q0) and sim.initial_defaults == (q0, v0)
    method = constrained_method(formulation, getattr(sim, "projection", False), s.method) if formulation else s.method
    res = sim.simulate(mf.times(), method=method, rtol=s.rtol, atol=s.atol)
    for q in mf.model.coords:
        column = table[:, header.index(q.name)]
        assert column[0] == pytest.approx(q0[mf.model.coords.index(q)], abs=1e-12)
        assert np.max(np.abs(res[q.name] - column)) < 1e-8, q.name
    # given values still win; the integrator takes the defaults too (ODE)
    assert sim.simulate([0.0, 0.1], q0=q0, v0=[0.0] * len(q0))[mf.model.coords[0].name][0] == q0[0]
    if formulation is None:  # the integrator, and simulate's prepared runs (its second call on), too
        assert list(sim.integrator().state[:len(q0)]) == q0
        for _ in range(2):
            assert [sim.simulate([0.0, 0.1])[q.name][0] for q in mf.model.coords] == q0
