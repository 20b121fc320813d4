"""Generalized speeds (issue 37): rotations without singularities and floating bases in
Pinocchio's layout, measured.

1. A free rigid body (principal moments 1, 2, 3) spun about its middle axis with a small
   perturbation (w0 = (0.01, 2, 0.01)), 40 s: it turns over again and again, through the
   attitudes where Z-Y-X angles are singular. Its orientation against an independent SO(3)
   integration (rotation matrix and Euler's equations, scipy DOP853 at 1e-13), for the ball
   joint with Z-Y-X angles (``rotation="ZYX"``, speeds q') and with a quaternion (speeds the
   body-frame angular velocity), on each method and tolerance: max |R - R_ref| over the run, max
   | |q| - 1 |, steps, and the wall time of ``simulate`` (median of interleaved rounds).
2. Floating-base robots from example-robot-data (``urdf.load(path, floating=True)``, the free
   flyer in Pinocchio's layout) against ``pin.buildModelFromUrdf(path, JointModelFreeFlyer())``:
   the time to build (derive, generate, compile; a fresh cache, the model-independent runtime
   built in it before the clock starts, as multibody.py does), the generated C's size, the
   error of v' against ``pin.aba`` at random states (relative to the reference's max norm), the
   forward dynamics per call from Python (``cm.rhs`` against ``pin.aba``, medians), and per call
   in compiled loops: the generated ``<prefix>_rhs`` in a C loop (the model's sources compiled as
   lagcodegen compiles its model library, ``MODEL_CFLAGS``) against ``pinocchio::aba`` in a C++
   loop (benchmarks/multibody_pin_aba.cpp, g++ -O3, the model as Pinocchio built it from the URDF,
   free flyer included), over the same 64 random states (normalized quaternions) in turn. The two
   loops run as separate processes, alternately, ``--rounds`` times; the table gives the medians,
   the median of the per-round ratios and their range. Our rhs computes both q' = G(q) v (the
   free flyer's quaternion rate and its position rate, a few dozen operations) and v' (with the
   URDF's joint damping); ``aba`` computes v' alone (tau = 0). Compiling the C++ loop takes 1-3
   minutes, so ``--quick`` leaves it out unless ``--pin-exe`` gives one already compiled.

This is a measuring instrument: it asserts nothing about the numbers it reports.

Usage::

    python benchmarks/generalized_speeds.py [--quick] [--rounds 3] [--robots solo12,anymal,talos] [--out DIR]
        [--pin-exe EXE] [--no-cpp] [--target SECONDS] [--robots-only]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

TAG = "generalized_speeds"
INERTIA = np.array([1.0, 2.0, 3.0])
W0 = np.array([0.01, 2.0, 0.01])
ROBOT_FILES = {"solo12": "solo_description/robots/solo12.urdf",
               "anymal": "anymal_b_simple_description/robots/anymal.urdf",
               "talos": "talos_data/robots/talos_full_v2.urdf"}
#: Pinocchio reads mimic joints as joints of their own unless told (its default, mimic=False).
LOAD = {"talos": {"mimic": "independent"}}


def so3_reference(times):
    from scipy.integrate import solve_ivp

    def f(t, y):
        R, w = y[:9].reshape(3, 3), y[9:]
        W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        return np.concatenate([(R @ W).ravel(), np.cross(INERTIA * w, w) / INERTIA])
    sol = solve_ivp(f, (times[0], times[-1]), np.concatenate([np.eye(3).ravel(), W0]), method="DOP853",
                    rtol=1e-13, atol=1e-14, t_eval=times)
    return sol.y[:9].T.reshape(-1, 3, 3)


def quat_matrix(q):
    x, y, z, w = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def euler_matrix(yaw, pitch, roll):
    cz, sz, cy, sy, cx, sx = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    return Rz @ Ry @ Rx


def tumbling(rounds: int, quick: bool) -> list[str]:
    import lagcodegen as lcg
    times = np.linspace(0.0, 40.0, 401)
    R_ref = so3_reference(times)
    models = {}
    for rotation in ("ZYX", "quaternion"):
        m = lcg.Model(f"tumbler_{rotation.lower()}")
        m.link("body", joint=lcg.Joint.spherical("ball", rotation=rotation), mass=1.0, inertia=tuple(INERTIA))
        models[rotation] = lcg.compile_model(m, jacobian=False)
    cases = []
    for rtol in ([1e-8, 1e-11] if quick else [1e-8, 1e-10, 1e-11, 1e-12]):
        for method in ("adams", "bdf", "taylor"):
            for rotation in ("ZYX", "quaternion"):
                cases.append((rotation, method, rtol))
    walls = {c: [] for c in cases}
    rows = {}
    for r in range(rounds):
        for case in cases:  # interleaved rounds
            rotation, method, rtol = case
            cm = models[rotation]
            # Euler angles: v0 = the angle rates giving w0 at zero angles (E = identity rows there, reversed)
            v0 = W0 if rotation == "quaternion" else W0[::-1]
            t0 = time.perf_counter()
            res = cm.simulate(times, v0=v0, method=method, rtol=rtol, atol=rtol / 10, max_steps=10**7,
                              raise_on_error=False)
            walls[case].append(time.perf_counter() - t0)
            if r == 0:
                if rotation == "quaternion":
                    R = np.array([quat_matrix(x) for x in res.y[:, :4]])
                    drift = np.abs(np.linalg.norm(res.y[:, :4], axis=1) - 1).max()
                else:
                    R = np.array([euler_matrix(*x) for x in res.y[:, :3]])
                    drift = float("nan")
                n = min(len(R), len(R_ref))
                rows[case] = (np.abs(R[:n] - R_ref[:n]).max(), drift, res.stats.get("steps", 0), res.status)
        H.progress(TAG, f"tumbling round {r + 1}/{rounds}")
    out = ["Tumbling free body through gimbal-lock attitudes (40 s), against SO(3) (DOP853 1e-13)",
           f"{'rotation':<11}{'method':<8}{'rtol':>7}{'max |R - R_ref|':>17}{'max ||q|-1|':>13}{'steps':>8}"
           f"{'wall ms':>9}{'status':>7}"]
    for case in cases:
        err, drift, steps, status = rows[case]
        out.append(f"{case[0]:<11}{case[1]:<8}{case[2]:>7.0e}{err:>17.2e}{drift:>13.2e}{steps:>8}"
                   f"{1e3 * statistics.median(walls[case]):>9.2f}{status:>7}")
    return out


C_LOOP = r"""
/* The generated ${prefix}_rhs over the states of argv[1] (NY values each, in turn) for about
 * argv[2] seconds: prints the nanoseconds per call (benchmarks/generalized_speeds.py). */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "${prefix}.h"
#define NY ${PREFIX}_NY
#define MAXS 256
static const double p[] = {${params}};
static double ys[MAXS][NY], ydot[NY];
static volatile double sink;

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
    FILE *f;
    int ns = 0, i, failures = 0;
    long calls = 64, k;
    double target, s, acc = 0;
    if (argc < 3 || (f = fopen(argv[1], "r")) == NULL)
        return 2;
    target = atof(argv[2]);
    while (ns < MAXS) {
        for (i = 0; i < NY; ++i)
            if (fscanf(f, "%lf", &ys[ns][i]) != 1)
                goto done;
        ++ns;
    }
done:
    fclose(f);
    if (ns == 0)
        return 3;
    for (;;) {
        double t0 = now();
        for (k = 0; k < calls; ++k) {
            failures += ${prefix}_rhs(0.0, ys[k % ns], p, ydot) != 0;
            acc += ydot[NY - 1];
        }
        s = now() - t0;
        if (s > target)
            break;
        calls *= 2;
    }
    sink = acc;
    if (failures)
        return 4;
    printf("%.6e\n", 1e9 * s / (double)calls);
    return 0;
}
"""


def c_loop(cm, folder: Path) -> Path:
    """The C loop over ``cm``'s generated rhs, compiled with the flags of lagcodegen's model
    library (:data:`lagcodegen.build.MODEL_CFLAGS`, -fPIC aside)."""
    from string import Template
    from lagcodegen.build import MODEL_CFLAGS
    code = cm.code
    folder.mkdir(parents=True, exist_ok=True)
    code.write(folder)
    params = ", ".join(repr(float(v)) for v in code.param_defaults) or "0.0"
    (folder / "c_loop.c").write_text(Template(C_LOOP).substitute(prefix=code.prefix, PREFIX=code.prefix.upper(),
                                                                 params=params))
    flags = [f for f in MODEL_CFLAGS if f != "-fPIC"]
    sources = [name for name in sorted(code.files) if name.endswith(".c")]
    cmd = [H.c_compiler(), *flags, "c_loop.c", *sources, "-o", "c_loop", "-lm"]
    proc = subprocess.run(cmd, cwd=folder, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"compiling the C loop failed:\n{' '.join(cmd)}\n{proc.stderr}")
    return folder / "c_loop"


def compiled_loops(cm, pm, states, iq, iv, pin_exe, rounds: int, target: float, folder: Path) -> tuple:
    """(median ns of our C loop, of Pinocchio's C++ loop, the median per-round ratio, its min and
    max, the C++ loop's accelerations at the first state, in Pinocchio's order)."""
    import multibody as MB
    exe = c_loop(cm, folder / "c")
    (folder / "ours.txt").write_text("\n".join(" ".join(repr(float(x)) for x in np.r_[q[iq], v[iv]])
                                               for q, v in states) + "\n")
    MB.write_pin_files(pm, states, folder)
    ours, theirs = [], []
    for _ in range(rounds):  # alternately
        r = subprocess.run([str(exe), str(folder / "ours.txt"), repr(target)], capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"the C loop failed ({r.returncode}): {r.stderr}")
        ours.append(float(r.stdout.split()[0]))
        r = subprocess.run([str(pin_exe), str(folder / "pin_model.txt"), str(folder / "pin_states.txt"), repr(target)],
                           capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"Pinocchio's C++ loop failed ({r.returncode}): {r.stderr}")
        out = r.stdout.split()
        theirs.append(float(out[0]))
        a_cpp = np.array([float(x) for x in out[2:]])
    ratios = [a / b for a, b in zip(ours, theirs)]
    return statistics.median(ours), statistics.median(theirs), statistics.median(ratios), min(ratios), \
        max(ratios), a_cpp


def robots(names: list[str], rounds: int, pin_exe=None, target: float = 0.2) -> list[str]:
    """The floating robots' table: build, size, error, per call from Python and (``pin_exe``,
    Pinocchio's compiled C++ loop, given) per call in compiled loops."""
    import pinocchio as pin
    import lagcodegen as lcg
    root = Path(pin.__file__).resolve().parents[4] / "share" / "example-robot-data" / "robots"
    out = ["Floating-base robots against Pinocchio's free flyer (pin.aba), same q and v layout",
           f"{'robot':<8}{'nq':>4}{'nv':>4}{'build s':>9}{'C kB':>8}{'rel err':>10}{'rhs us':>8}{'aba us':>8}"
           f"{'ratio':>7}{'C ns':>8}{'C++ ns':>8}{'C/C++':>7}{'range':>12}{'C++ err':>9}"]
    for name in names:
        file = root / ROBOT_FILES[name]
        with tempfile.TemporaryDirectory() as cache:
            old = os.environ.get("LAGCODEGEN_CACHE")
            os.environ["LAGCODEGEN_CACHE"] = cache
            try:
                lcg.build.runtime()  # the model-independent runtime (built once per cache), untimed
                t0 = time.perf_counter()
                cm = lcg.compile_model(lcg.urdf.load(file, floating=True, **LOAD.get(name, {})))
                build = time.perf_counter() - t0
            finally:
                if old is None:
                    os.environ.pop("LAGCODEGEN_CACHE")
                else:
                    os.environ["LAGCODEGEN_CACHE"] = old
            size = sum(len(t) for k, t in cm.code.files.items() if k.endswith((".c", ".h"))) / 1024
            pm = pin.buildModelFromUrdf(str(file), pin.JointModelFreeFlyer())
            data = pm.createData()
            damping = np.zeros(pm.nv)
            for jname, joint in lcg.urdf.read(file).joints.items():
                if pm.existJointName(jname) and joint.dynamics is not None:
                    damping[pm.joints[pm.getJointId(jname)].idx_v] = joint.dynamics.damping
            # the same joints in Pinocchio's order (its parser orders siblings its own way; lagcodegen
            # keeps the file's): our q, v entries -> Pinocchio's
            iq, iv = list(range(7)), list(range(6))
            for c in cm.state_names[7:cm.nq]:
                jm = pm.joints[pm.getJointId(c)]
                iq += list(range(jm.idx_q, jm.idx_q + jm.nq))
                iv += list(range(jm.idx_v, jm.idx_v + jm.nv))
            rng = np.random.default_rng(0)
            err = 0.0
            for _ in range(10):
                q = pin.randomConfiguration(pm, -np.ones(pm.nq), np.ones(pm.nq))
                v = rng.normal(size=pm.nv)
                a = pin.aba(pm, data, q, v, -damping * v)
                err = max(err, np.abs(cm.rhs(0.0, np.r_[q[iq], v[iv]])[pm.nq:] - a[iv]).max() / np.abs(a).max())
            y = np.r_[q[iq], v[iv]]
            tau = -damping * v
            ours, theirs = [], []
            for _ in range(rounds):
                ours.append(min(timeit.repeat(lambda: cm.rhs(0.0, y), number=2000, repeat=3)) / 2000)
                theirs.append(min(timeit.repeat(lambda: pin.aba(pm, data, q, v, tau), number=2000, repeat=3)) / 2000)
            a_us, b_us = 1e6 * statistics.median(ours), 1e6 * statistics.median(theirs)
            row = (f"{name:<8}{pm.nq:>4}{pm.nv:>4}{build:>9.2f}{size:>8.0f}{err:>10.1e}{a_us:>8.2f}{b_us:>8.2f}"
                   f"{a_us / b_us:>7.2f}")
            if pin_exe is not None:
                H.progress(TAG, f"{name}: C loop against Pinocchio's C++ loop ...")
                states = [(pin.randomConfiguration(pm, -np.ones(pm.nq), np.ones(pm.nq)), rng.normal(size=pm.nv))
                          for _ in range(64)]
                with tempfile.TemporaryDirectory() as tmp:
                    c_ns, cpp_ns, ratio, lo, hi, a_cpp = compiled_loops(cm, pm, states, iq, iv, pin_exe, rounds,
                                                                        target, Path(tmp))
                ref = pin.aba(pm, data, states[0][0], states[0][1], np.zeros(pm.nv))  # the C++ loop's model is pm
                cpp_err = np.abs(a_cpp - ref).max() / np.abs(ref).max()
                row += f"{c_ns:>8.0f}{cpp_ns:>8.0f}{ratio:>7.2f}{f'{lo:.2f}-{hi:.2f}':>12}{cpp_err:>9.1e}"
            out.append(row)
            H.progress(TAG, f"{name}: built in {build:.1f} s")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="two tolerances, Solo12 only, one round")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--robots", default="solo12,anymal,talos")
    ap.add_argument("--out", type=Path, help="also write the table to OUT/generalized_speeds.txt")
    ap.add_argument("--pin-exe", type=Path, help="benchmarks/multibody_pin_aba.cpp already compiled")
    ap.add_argument("--no-cpp", action="store_true", help="leave out the C loop against Pinocchio's C++ loop")
    ap.add_argument("--target", type=float, default=0.2, help="seconds per compiled timing loop")
    ap.add_argument("--robots-only", action="store_true", help="leave out the tumbling body")
    args = ap.parse_args(argv)
    rounds = 1 if args.quick else args.rounds
    names = ["solo12"] if args.quick else [r for r in args.robots.split(",") if r]
    unknown = [r for r in names if r not in ROBOT_FILES]
    if unknown:
        ap.error(f"unknown robots {unknown}; known: {', '.join(ROBOT_FILES)}")
    load0 = H.load_average()
    lines = [] if args.robots_only else tumbling(rounds, args.quick)
    build_dir = tempfile.TemporaryDirectory()
    if args.no_cpp:
        pin_exe, how = None, "left out (--no-cpp)"
    elif args.pin_exe is not None:
        pin_exe, how = args.pin_exe, f"{args.pin_exe} (given)"
    elif args.quick:
        pin_exe, how = None, "left out (--quick without --pin-exe)"
    else:
        import multibody as MB
        H.progress(TAG, "compiling Pinocchio's ABA loop (g++ -O3, 1-3 minutes) ...")
        pin_exe, how = MB.pin_cpp(Path(build_dir.name))  # None and the reason when it cannot
    try:
        lines += [""] + robots(names, rounds, pin_exe, args.target)
        lines.append(f"Pinocchio's C++ loop: {how}")
    except ImportError:
        lines += ["", "Pinocchio is not installed (pip install pin example-robot-data): robots not measured"]
    text = "\n".join(H.machine_lines("Generalized speeds", (load0, H.load_average())) + [""] + lines)
    print(text)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "generalized_speeds.txt").write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
