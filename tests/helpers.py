"""Shared helpers of the test modules: strict compiler flags and the constrained systems that
several stages' tests use (imported as ``from helpers import ...``; tests/ is on pytest's path)."""

import numpy as np
import sympy as sp

import lagcodegen as lcg
from lagcodegen.theory.constraints import ConstrainedSystem

STRICT_CFLAGS = ["-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic"]
STRICT_FFLAGS = ["-Wall", "-Wextra", "-std=f2008", "-Werror"]

#: A two-link arm whose elbow j2 mimics the shoulder j1 (q2 = 0.5 q1 + 0.1), both revolute (as
#: Pinocchio's mimic joints must be), the shoulder limited to +-0.3 rad.
MIMIC_ARM = """<robot name="mimic_arm"><link name="base"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 1 0"/>
    <limit lower="-0.3" upper="0.3" effort="1" velocity="1"/></joint>
  <link name="a"><inertial><origin xyz="0 0 -0.5"/><mass value="1"/>
    <inertia ixx="0.01" iyy="0.02" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0 0 -1"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/><mimic joint="j1" multiplier="0.5" offset="0.1"/></joint>
  <link name="b"><inertial><origin xyz="0 0 -0.5"/><mass value="1.5"/>
    <inertia ixx="0.01" iyy="0.03" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>"""

G = 9.81
TH0 = 1.0  # initial pendulum angle (rad)


# ---------------------------------------------------------------------- systems
def cartesian_pendulum(name="cpend"):
    """Bob at (x, y) with x^2 + y^2 = l^2 (eq. 4.1). A = (2x, 2y): the rod tension is -2 l lambda."""
    m = lcg.Model(name)
    x, y = m.coordinates("x y")
    l, g, mass = m.parameters(l=1.0, g=G, m=1.0)
    m.particle("bob", mass, (x, y))
    m.gravity(g)
    return ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - l ** 2])


def atwood(name="atwood"):
    """Two masses on a string over a massless pulley; x1, x2 measured downwards, x1 + x2 = L."""
    m = lcg.Model(name)
    x1, x2 = m.coordinates("x1 x2")
    m1, m2, g, L = m.parameters(m1=3.0, m2=1.0, g=G, L=2.0)
    m.particle("b1", m1, (0, -x1))
    m.particle("b2", m2, (1, -x2))
    m.gravity(g)
    return ConstrainedSystem(m, holonomic=[x1 + x2 - L])


def knife_edge(name="knife"):
    """Knife edge on an inclined plane: no velocity across the blade, sin(th) x' - cos(th) y' = 0."""
    m = lcg.Model(name)
    x, y, th = m.coordinates("x y theta")
    mass, Iz, g, al = m.parameters(m=1.0, Iz=0.1, g=G, alpha=0.3)
    m.kinetic_energy(mass / 2 * (m.dot(x) ** 2 + m.dot(y) ** 2) + Iz / 2 * m.dot(th) ** 2)
    m.potential_energy(-mass * g * sp.sin(al) * x)
    return ConstrainedSystem(m, nonholonomic=[([sp.sin(th), -sp.cos(th), 0], 0)])


def pendulum_q0(th=TH0, l=1.0):
    return [l * np.sin(th), -l * np.cos(th)]


def mixed_system():
    """Holonomic and nonholonomic rows together: a knife edge held on the line y = x sin(t)/4... plus events."""
    cs = knife_edge(name="mixed")
    m = cs.model
    x, y, th = m.coords
    return ConstrainedSystem(m, holonomic=[y - x * sp.sin(m.t) / 4],
                             nonholonomic=[([sp.sin(th), -sp.cos(th), 0], 0)], inequalities=[3 - x])




# ---------------------------------------------------------------------- the Whipple bicycle
#: Benchmark parameters of Meijaard, Papadopoulos, Ruina, Schwab (2007), Proc. R. Soc. A 463,
#: 1955-1982, Table 1 (lam: the steer axis tilt pi/10, set below).
WHIPPLE_PARAMETERS = dict(
    w=1.02, c=0.08, g=9.81,
    rR=0.3, mR=2.0, IRxx=0.0603, IRyy=0.12,
    xB=0.3, zB=-0.9, mB=85.0, IBxx=9.2, IBxz=2.4, IByy=11.0, IBzz=2.8,
    xH=0.9, zH=-0.7, mH=4.0, IHxx=0.05892, IHxz=-0.00756, IHyy=0.06, IHzz=0.00708,
    rF=0.35, mF=3.0, IFxx=0.1405, IFyy=0.28)


def _rx(a):
    return sp.Matrix([[1, 0, 0], [0, sp.cos(a), -sp.sin(a)], [0, sp.sin(a), sp.cos(a)]])


def _ry(a):
    return sp.Matrix([[sp.cos(a), 0, sp.sin(a)], [0, 1, 0], [-sp.sin(a), 0, sp.cos(a)]])


def _rz(a):
    return sp.Matrix([[sp.cos(a), -sp.sin(a), 0], [sp.sin(a), sp.cos(a), 0], [0, 0, 1]])


def whipple_bicycle(name="whipple", check_integrability=False):
    """The Whipple bicycle of Meijaard et al. (2007) as a ConstrainedSystem (written here from the
    paper's description, sec. 2 and Table 1; conventions as there: x forward, z down, y to the
    right; lean about x, steer about the steer axis, both right-handed).

    Coordinates: the rear contact point (x, y), yaw psi, lean phi, rear frame pitch theta (0 in the
    paper's reference configuration, where both wheels touch), steer delta, the wheels' rotation
    angles thR, thF relative to their frames. Four rigid bodies: rear wheel R, rear frame B, front
    frame H, front wheel F (knife-edge wheels, point contact). Constraints: the front wheel's lowest
    point on the ground (holonomic: its height, z = 0), and no slip at both contacts (the material
    point of each wheel at its contact has no horizontal velocity: 4 nonholonomic rows).
    """
    m = lcg.Model(name)
    x, y, psi, phi, theta, delta, thR, thF = m.coordinates("x y psi phi theta delta thR thF")
    p = {k: m.parameter(k, v) for k, v in WHIPPLE_PARAMETERS.items()}
    lam = m.parameter("lam", float(np.pi / 10))
    w, c, rR, rF = p["w"], p["c"], p["rR"], p["rF"]
    m.gravity(p["g"], up=(0, 0, -1))  # z points down

    Ryaw = _rz(psi)
    Rlean = Ryaw * _rx(phi)
    RB = Rlean * _ry(theta)  # rear frame: yaw, lean, pitch
    steer = _ry(lam) * _rz(delta) * _ry(-lam)  # about the steer axis (sin lam, 0, cos lam) of B
    RH = RB * steer
    P = sp.Matrix([x, y, 0])
    cR = P + Rlean * sp.Matrix([0, 0, -rR])  # rear wheel centre, above the contact in the wheel plane
    # Reference configuration (all angles 0): rear contact at the origin, rear centre (0, 0, -rR),
    # the steer axis meets the ground at (w + c, 0, 0), front centre (w, 0, -rF).
    axis = cR + RB * sp.Matrix([w + c, 0, rR])
    cF = axis + RH * sp.Matrix([-c, 0, -rF])
    gB = cR + RB * sp.Matrix([p["xB"], 0, p["zB"] + rR])
    gH = axis + RH * sp.Matrix([p["xH"] - w - c, 0, p["zH"]])

    m.rigid_body("R", p["mR"], [p["IRxx"], p["IRyy"], p["IRxx"]], cR, RB * _ry(thR))
    m.rigid_body("B", p["mB"], sp.Matrix([[p["IBxx"], 0, p["IBxz"]], [0, p["IByy"], 0], [p["IBxz"], 0, p["IBzz"]]]),
                 gB, RB)
    m.rigid_body("H", p["mH"], sp.Matrix([[p["IHxx"], 0, p["IHxz"]], [0, p["IHyy"], 0], [p["IHxz"], 0, p["IHzz"]]]),
                 gH, RH)
    m.rigid_body("F", p["mF"], [p["IFxx"], p["IFyy"], p["IFxx"]], cF, RH * _ry(thF))

    # Front contact: from the front centre, rF along the direction in the wheel plane that points
    # most downwards, d = (e_z - a_z a) / sqrt(1 - a_z^2), a the front axle.
    a = RH * sp.Matrix([0, 1, 0])
    s = sp.sqrt(1 - a[2] ** 2)
    down = (sp.Matrix([0, 0, 1]) - a[2] * a) / s
    contact_F = cF + rF * down
    holonomic = [cF[2] + rF * s]  # the height of that point (z = contact_F[2] simplified)

    qs = [x, y, psi, phi, theta, delta, thR, thF]
    qd = [m.dot(q) for q in qs]

    def velocity(point):
        return sp.Matrix([sum(sp.diff(comp, q) * v for q, v in zip(qs, qd)) for comp in point])

    # angular velocities (world frame) as sums of rates about the joint axes
    ez, ex, ey = sp.Matrix([0, 0, 1]), sp.Matrix([1, 0, 0]), sp.Matrix([0, 1, 0])
    wB = m.dot(psi) * ez + m.dot(phi) * (Ryaw * ex) + m.dot(theta) * (Rlean * ey)
    wR = wB + m.dot(thR) * (Rlean * ey)
    wF = wB + m.dot(delta) * (RB * _ry(lam) * ez) + m.dot(thF) * a

    rows = []
    for centre, w_, contact in ((cR, wR, P), (cF, wF, contact_F)):
        # velocity of the wheel's material point at the contact: v_centre + w x (contact - centre)
        vel = velocity(centre) + w_.cross(contact - centre)
        for k in (0, 1):
            rows.append([sp.diff(vel[k], v) for v in qd])
    return ConstrainedSystem(m, holonomic=holonomic, nonholonomic=rows, check_integrability=check_integrability)


def whipple_straight_run(v):
    """(q0, v0) of the upright straight run at speed v (the wheels roll: thR' = -v/rR, thF' = -v/rF)."""
    P = WHIPPLE_PARAMETERS
    return [0.0] * 8, [v, 0, 0, 0, 0, 0, -v / P["rR"], -v / P["rF"]]


def run_cvode_main_sanitized(tmp_path, cc, code, main: str) -> None:
    """The CVODE driver of the generated ``code`` compiled strict C99 (-Werror), then ``main``
    (its PREFIX, PREFIXU and PARAMS replaced by the model's prefix, upper-cased prefix and
    default parameters) built with it under AddressSanitizer and UBSan and run: asserts it exits
    0 with nothing reported."""
    import os
    import subprocess

    from lagcodegen.build import driver_sources, find_sundials
    sundials = find_sundials()
    code.write(tmp_path)
    for fname, text in driver_sources(code, sundials).items():
        (tmp_path / fname).write_text(text)
    pre = code.prefix
    strict = subprocess.run([cc, *STRICT_CFLAGS, "-c", "lcg_cvode.c", "-o", "d.o"], cwd=tmp_path,
                            capture_output=True, text=True)
    assert strict.returncode == 0, strict.stderr
    params = list(code.param_defaults)
    (tmp_path / "main.c").write_text(main.replace("PREFIXU", pre.upper()).replace("PREFIX", pre).replace(
        "PARAMS", f"((const double[]){{{', '.join(map(repr, params))}}})"))
    cmd = [cc, "-g", "-O1", "-std=c99", "-fsanitize=address,undefined", "-fno-sanitize-recover=all", "main.c",
           code.source_name, f"{pre}_table.c", "lcg_cvode.c", "lcg_inputs.c", "-o", "main", "-pthread",
           *sundials.link_args(), "-lm"]
    proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    run = subprocess.run(["./main"], cwd=tmp_path, capture_output=True, text=True,
                         env={**os.environ, "ASAN_OPTIONS": "detect_leaks=1", "UBSAN_OPTIONS": "print_stacktrace=1"})
    assert run.returncode == 0, run.stdout + run.stderr
    assert "runtime error" not in run.stderr and "AddressSanitizer" not in run.stderr


# ---------------------------------------------------------------------- Ctrl-C in a subprocess
def interrupt_when_ready(script) -> tuple[int, str, float]:
    """Run the Python file ``script`` (with this checkout on PYTHONPATH), wait for its line
    "ready", let it run 0.5 s more and send SIGINT: (its exit code, its stderr, the seconds from
    the signal to its end)."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, PYTHONPATH=str(root)))
    try:
        line = proc.stdout.readline().strip()
        assert line == "ready", proc.communicate(timeout=60)[1]
        time.sleep(0.5)
        sent = time.perf_counter()
        proc.send_signal(signal.SIGINT)
        err = proc.communicate(timeout=60)[1]
        took = time.perf_counter() - sent
    finally:
        proc.kill()
    return proc.returncode, err, took
