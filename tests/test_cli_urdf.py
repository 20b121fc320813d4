"""The lagcodegen command on URDF robots: generate, simulate and info take a .urdf file."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from helpers import MIMIC_ARM

ROOT = Path(__file__).resolve().parents[1]
ARM = ROOT / "examples" / "two_link_arm.urdf"


def run(*args, cwd=None):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "lagcodegen", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd, env=env, timeout=600)


def test_generate_writes_the_robot_model(tmp_path):
    out = tmp_path / "gen"
    proc = run("generate", ARM, "-o", out)
    assert proc.returncode == 0, proc.stderr
    assert "loaded" in proc.stderr and "(2 coordinates)" in proc.stderr
    header = (out / "two_link_arm.h").read_text()
    assert "#define TWO_LINK_ARM_NQ 2" in header and "#define TWO_LINK_ARM_NP 1" in header  # g stays adjustable
    assert "y[0] = shoulder" in header and "y[1] = elbow" in header
    assert (out / "two_link_arm.c").is_file()
    assert run("generate", ARM, "-o", out, "--check", "-q").returncode == 0  # up to date


def test_simulate_a_urdf(tmp_path):
    """The arm at rest hanging straight down, gravity set to 1.62 (--set g=...)."""
    proc = run("simulate", ARM, "-o", tmp_path / "arm.csv", "--t-end", "2", "--set", "g=1.62", "-q")
    assert proc.returncode == 0, proc.stderr
    header = (tmp_path / "arm.csv").read_text().splitlines()[0].split(",")
    assert header[:5] == ["t", "shoulder", "elbow", "shoulder_dot", "elbow_dot"]
    data = np.loadtxt(tmp_path / "arm.csv", delimiter=",", skiprows=1)
    assert data[-1, 0] == pytest.approx(2.0)
    # at rest hanging straight down is an equilibrium: the run stays there exactly
    assert np.all(data[:, 1:5] == 0)


def test_simulate_a_pendulum_released_from_the_horizontal(tmp_path):
    """A compound pendulum about y, its centre of mass on +x at q = 0: released at rest it swings
    down through q = pi/2 to the other horizontal, q = pi, conserving T + V."""
    urdf = tmp_path / "swing.urdf"
    urdf.write_text('<robot name="swing"><link name="base"/><joint name="hinge" type="continuous">'
                    '<parent link="base"/><child link="bar"/><axis xyz="0 1 0"/></joint><link name="bar"><inertial>'
                    '<origin xyz="0.5 0 0"/><mass value="2"/><inertia ixx="0.001" iyy="0.17" izz="0.17" ixy="0" '
                    'ixz="0" iyz="0"/></inertial></link></robot>')
    proc = run("simulate", urdf, "-o", tmp_path / "swing.csv", "--t-end", "3", "--n-out", "3001",
               "--outputs", "energy", "--rtol", "1e-10", "--atol", "1e-12", "-q")
    assert proc.returncode == 0, proc.stderr
    header = (tmp_path / "swing.csv").read_text().splitlines()[0].split(",")
    data = np.loadtxt(tmp_path / "swing.csv", delimiter=",", skiprows=1)
    q, energy = data[:, header.index("hinge")], data[:, header.index("energy")]
    assert q.min() > -1e-9 and q.max() == pytest.approx(np.pi, abs=1e-3)
    assert np.abs(energy - energy[0]).max() < 1e-7  # m g c = 9.81 J: 1e-8 relative


def test_info_and_bad_urdf_exit_with_a_located_message(tmp_path):
    proc = run("info", ARM)
    assert proc.returncode == 0, proc.stderr
    assert "shoulder" in proc.stdout and "elbow" in proc.stdout
    bad = tmp_path / "bad.urdf"
    bad.write_text('<robot name="r"><link name="a"/><joint name="j" type="hinge"><parent link="a"/>'
                   '<child link="b"/></joint><link name="b"/></robot>')
    proc = run("generate", bad, "-o", tmp_path / "gen")
    assert proc.returncode != 0
    assert f"{bad}:1: joint 'j': unknown joint type 'hinge'" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_urdf_loading_options_on_the_command_line(tmp_path):
    """--urdf KEY=VALUE takes urdf.load's keywords: a robot with a mimic joint runs by default (the
    mimic joint driven by its leader: one coordinate), is refused with mimic=error (exit 1, the
    message naming mimic), runs with mimic=independent, and with limits=true its
    joints stop at their limits (the run goes to its end); a bad key is a usage error naming the
    keys; URDF options on a .toml file are refused; generate records them in its manifest."""
    urdf = tmp_path / "mimic_arm.urdf"
    urdf.write_text(MIMIC_ARM)
    driven = run("simulate", urdf, "-o", tmp_path / "a.csv", "-q")
    assert driven.returncode == 0, driven.stderr
    assert (tmp_path / "a.csv").read_text().splitlines()[0].split(",")[:3] == ["t", "j1", "j1_dot"]
    refused = run("simulate", urdf, "-o", tmp_path / "a.csv", "--urdf", "mimic=error", "-q")
    assert refused.returncode == 1 and "mimic" in refused.stderr and "Traceback" not in refused.stderr
    ok = run("simulate", urdf, "-o", tmp_path / "a.csv", "--t-end", "2", "--initial", "j1=0.25",
             "--urdf", "mimic=independent", "--urdf", "limits=true", "-q")
    assert ok.returncode == 0, ok.stderr
    data = np.loadtxt(tmp_path / "a.csv", delimiter=",", skiprows=1)
    header = (tmp_path / "a.csv").read_text().splitlines()[0].split(",")
    assert data[-1, 0] == pytest.approx(2.0)
    assert np.all(np.abs(data[:, header.index("j1")]) <= 0.3 + 1e-6)  # the stops hold
    bad = run("simulate", urdf, "-o", tmp_path / "a.csv", "--urdf", "mimc=independent", "-q")
    assert bad.returncode == 2 and "floating, mimic, limits" in bad.stderr
    toml = run("simulate", ROOT / "examples" / "pendulum.toml", "-o", tmp_path / "p.csv", "--urdf", "mimic=independent",
               "-q")
    assert toml.returncode == 1 and "apply to .urdf files only" in toml.stderr
    gen = run("generate", urdf, "-o", tmp_path / "gen", "--urdf", "mimic=independent", "-q")
    assert gen.returncode == 0, gen.stderr
    assert '"urdf"' in (tmp_path / "gen" / "mimic_arm.lagcodegen.json").read_text()


def test_simulate_a_floating_robot_falls_freely(tmp_path):
    """--floating: the arm's root on a free joint in Pinocchio's layout (q: x y z qx qy qz qw, v:
    linear and angular velocity in the root's frame); released at rest it falls freely, its
    base's height z = z0 - g t^2 / 2 with the quaternion unchanged (no torque on the whole)."""
    proc = run("simulate", ROOT / "examples" / "ur_like_arm.urdf", "--floating", "-o", tmp_path / "fall.csv",
               "--t-end", "1", "--rtol", "1e-10", "--atol", "1e-12", "-q")
    assert proc.returncode == 0, proc.stderr
    header = (tmp_path / "fall.csv").read_text().splitlines()[0].split(",")
    assert header[1:8] == ["root_joint_x", "root_joint_y", "root_joint_z", "root_joint_qx", "root_joint_qy",
                           "root_joint_qz", "root_joint_qw"]
    assert "root_joint_vx" in header and "root_joint_wz" in header
    data = np.loadtxt(tmp_path / "fall.csv", delimiter=",", skiprows=1)
    t, z = data[:, 0], data[:, header.index("root_joint_z")]
    assert np.abs(z + 9.81 * t ** 2 / 2).max() < 1e-8
    assert np.abs(data[:, header.index("root_joint_qw")] - 1).max() < 1e-9


def test_urdf_options_as_flags(tmp_path):
    """--mimic, --lock, --limits, --friction are --urdf KEY=VALUE items of their own: a locked
    elbow leaves one coordinate; --mimic independent gives the mimic joint its coordinate."""
    proc = run("simulate", ARM, "--lock", "elbow", "-o", tmp_path / "l.csv", "-q")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "l.csv").read_text().splitlines()[0].split(",") == ["t", "shoulder", "shoulder_dot"]
    urdf = tmp_path / "mimic_arm.urdf"
    urdf.write_text(MIMIC_ARM)
    proc = run("simulate", urdf, "--mimic", "independent", "--friction", "smooth", "-o", tmp_path / "m.csv", "-q")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "m.csv").read_text().splitlines()[0].split(",")[:3] == ["t", "j1", "j2"]
    bad = run("simulate", urdf, "--mimic", "banana", "-o", tmp_path / "m.csv", "-q")
    assert bad.returncode == 1 and "mimic must be one of driven" in bad.stderr


def test_simulate_the_ur5_with_its_limits_prints_the_contact_log(tmp_path):
    """--limits true on example-robot-data's UR5: the run goes to its end (t = 3) with the elbow
    never past its stop (-pi), and the contact log lists the elbow's impact on its lower stop and
    its release, at the times the Python API's run (compile_urdf(limits=True)) finds."""
    import pinocchio as pin

    import lagcodegen as lcg
    ur5 = Path(pin.__file__).resolve().parents[4] / "share/example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"
    proc = run("simulate", ur5, "--limits", "true", "-o", tmp_path / "ur5.csv", "--t-end", "3", "--initial",
               "shoulder_lift_joint=-1.0,elbow_joint=2.8", "--rtol", "1e-10", "--atol", "1e-12")
    assert proc.returncode == 0, proc.stderr
    header = (tmp_path / "ur5.csv").read_text().splitlines()[0].split(",")
    data = np.loadtxt(tmp_path / "ur5.csv", delimiter=",", skiprows=1)
    assert data[-1, 0] == pytest.approx(3.0)
    assert data[:, header.index("elbow_joint")].min() >= -3.14159265359 - 1e-8
    res = lcg.compile_urdf(ur5, limits=True).simulate([0.0, 3.0], q0=[0.0, -1.0, 2.8, 0.0, 0.0, 0.0], v0=[0.0] * 6,
                                                       rtol=1e-10, atol=1e-12)
    log = [line for line in proc.stderr.splitlines() if "contact 4 (g = elbow_joint + 3.14159265359)" in line]
    assert [line.split()[-7] for line in log] == [r.kind + "," for r in res.impacts] == ["stick,", "release,"]
    for line, record in zip(log, res.impacts):
        assert float(line.split("t = ")[1].split(":")[0]) == pytest.approx(record.t, abs=1e-6)


def test_simulate_a_urdf_again_loads_it_from_the_cache(tmp_path):
    """A second `simulate` of the same .urdf with the same options (a new process, the same cache)
    loads the compiled model from compile_urdf's cache (nothing derived; the key's other parts are
    checked in test_api) and writes the same file to the bit, its contact log the same."""
    arm = tmp_path / "arm.urdf"  # a robot of its own name: not in the session's cache yet
    arm.write_text(ARM.read_text().replace('<robot name="two_link_arm"', '<robot name="arm_again"'))
    argv = ["simulate", arm, "--t-end", "2", "--initial", "shoulder=2.5,shoulder_dot=4", "--limits", "stop:0.5"]
    first = run(*argv, "-o", tmp_path / "a.csv")
    assert first.returncode == 0, first.stderr
    assert "derived, generated and compiled" in first.stderr and "nothing derived" not in first.stderr
    again = run(*argv, "-o", tmp_path / "b.csv")
    assert again.returncode == 0, again.stderr
    assert "from the cache (nothing derived)" in again.stderr
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    log = [line for line in again.stderr.splitlines() if "contact 1 (g = 3.0 - shoulder)" in line]
    assert log and "bounce" in log[0] and log == [line for line in first.stderr.splitlines() if "contact 1 (" in line]


def test_simulate_the_panda_by_default(tmp_path):
    """`lagcodegen simulate panda.urdf` with no option (issue 38): the Franka Panda loads with its
    gripper (the second finger driven by the first: 8 coordinates, as Pinocchio's mimic=True) and
    runs from its neutral pose, the same trajectory as the Python API's compile_urdf run."""
    import pinocchio as pin

    import lagcodegen as lcg
    panda = Path(pin.__file__).resolve().parents[4] / "share/example-robot-data/robots/panda_description/urdf/panda.urdf"
    proc = run("simulate", panda, "-o", tmp_path / "panda.csv", "--t-end", "0.5", "--n-out", "6", "-q")
    assert proc.returncode == 0, proc.stderr
    header = (tmp_path / "panda.csv").read_text().splitlines()[0].split(",")
    data = np.loadtxt(tmp_path / "panda.csv", delimiter=",", skiprows=1)
    assert header[1:10] == [f"panda_joint{i}" for i in range(1, 8)] + ["panda_finger_joint1", "panda_joint1_dot"]
    want = lcg.compile_urdf(panda).simulate(data[:, 0], q0=np.zeros(8), rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(data[:, 1:17], want.y, rtol=0, atol=1e-12)
