"""Rigid-body trees (issue 22): spatial chains n = 3..30 and the Franka Panda arm (its URDF from
example-robot-data), built with Model.link and evaluated along the tree, measured against
Pinocchio.

Each row is built in a fresh Python process that reports derive, generate (C code, no Jacobian)
and build (``lagcodegen.build``) wall times, bytes of generated C, the peak resident memory of
the process and of its compilers (ru_maxrss), the error of the accelerations against Pinocchio's
ABA (the URDF's joint damping, which lagcodegen takes as Rayleigh dissipation, given to ABA as
the torques -d q'; relative to the infinity norm of the reference, max over 20 random states), the forward
dynamics per call from Python (``sim.rhs`` against ``pin.aba``, medians of timeit blocks) and in
a C loop (the generated ``<prefix>_rhs`` called from a small C program, benchmarks/_harness.py,
the model compiled with lagcodegen's flags). Pinocchio's ABA in a C++ loop is
benchmarks/multibody_pin_aba.cpp, compiled with g++ -O3 -DNDEBUG against the pin wheel's headers
(cmeel prefix; the wheel ships no Eigen, so the first Eigen found under site-packages is used);
its joints are the kinds Pinocchio built them as (RX, RY, RZ where the axis is one, else
unaligned). If it cannot be compiled, the table says so and only the Python timings compare.

This is a measuring instrument: it asserts nothing about the numbers it reports.

Usage::

    python benchmarks/multibody.py [--quick] [--out DIR] [--sizes 3,7,...] [--target SECONDS]
"""

from __future__ import annotations

import argparse
import json
import os
import site
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

TAG = "multibody"
HERE = Path(__file__).resolve().parent

# One row, cold, in a fresh interpreter.
_ROW = r"""
import json, resource, sys, time, timeit
from pathlib import Path
from types import SimpleNamespace
args = json.loads(sys.argv[1])
sys.path.insert(0, args["bench"])
import numpy as np
import multibody as MB
import _harness as H
import lagcodegen as lcg
import pinocchio as pin
m, pm = MB.panda() if args["model"] == "panda" else MB.chain(args["n"])
n = m.n
t0 = time.perf_counter(); eom = lcg.derive(m); t1 = time.perf_counter()
code = lcg.generate_code(lcg.Scene(eom, jacobian=False)); t2 = time.perf_counter()
sim = lcg.build_code(code); t3 = time.perf_counter()
csize = sum(len(v) for k, v in code.files.items() if k.endswith(".c") and "dynamics" not in k)
rng = np.random.default_rng(1)
data = pm.createData()
states = [(rng.uniform(-2, 2, n), rng.uniform(-1, 1, n)) for _ in range(20)]
err = 0.0
for q, v in states:
    a = sim.rhs(0.0, np.r_[q, v])[n:]
    ref = pin.aba(pm, data, q, v, -np.asarray(pm.damping) * v)  # the URDF's joint damping as torques
    err = max(err, float(np.abs(a - ref).max() / np.abs(ref).max()))
y = np.r_[states[0][0], states[0][1]]
q, v, z = states[0][0], states[0][1], np.zeros(n)
py_lcg = min(timeit.repeat(lambda: sim.rhs(0.0, y), number=2000, repeat=5)) / 2000 * 1e9
py_pin = min(timeit.repeat(lambda: pin.aba(pm, data, q, v, z), number=2000, repeat=5)) / 2000 * 1e9
tmp = Path(args["tmp"])
c_rhs = H.c_call_costs(sim.code, tmp, SimpleNamespace(repeats=3, c_target=args["target"]))["rhs"]
MB.write_pin_files(pm, states, tmp)
self_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
child_rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
print("ROW " + json.dumps(dict(n=n, derive=t1 - t0, generate=t2 - t1, build=t3 - t2, c_bytes=csize, rss=self_rss,
                               cc_rss=child_rss, err=err, py_lcg=py_lcg, py_pin=py_pin, c_rhs=c_rhs)))
"""


def chain(n: int, seed: int = 0):
    """A random spatial chain of n revolute links (axes z, x, y and an unaligned one in turn, random
    placements and full inertias), as a lagcodegen Model and a Pinocchio model."""
    import numpy as np
    import pinocchio as pin

    import lagcodegen as lcg
    rng = np.random.default_rng(seed)
    m = lcg.Model(f"chain{n}")
    g, = m.parameters(g=9.81)
    m.gravity(g)
    pm = pin.Model()
    pm.gravity = pin.Motion(np.array([0, 0, -9.81, 0, 0, 0]))
    parent, jid = None, 0
    for i in range(n):
        R, t = pin.rpy.rpyToMatrix(*rng.uniform(-3, 3, 3)), rng.uniform(-0.3, 0.3, 3)
        ax = np.array([(0, 0, 1), (1, 0, 0), (0, 1, 0), tuple(rng.normal(size=3))][i % 4], dtype=float)
        ax /= np.linalg.norm(ax)
        A = rng.normal(size=(3, 3))
        mass, c, I = rng.uniform(0.5, 2), rng.uniform(-0.2, 0.2, 3), A @ A.T + 0.1 * np.eye(3)
        parent = m.link(f"l{i}", parent=parent, joint=lcg.Joint.revolute(f"j{i}", tuple(ax)),
                        origin=lcg.Placement(tuple(t), rotation=R.tolist()), mass=mass, com=tuple(c),
                        inertia=(I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2])).name
        jm = {0: pin.JointModelRZ, 1: pin.JointModelRX, 2: pin.JointModelRY}.get(i % 4)
        jid = pm.addJoint(jid, jm() if jm else pin.JointModelRevoluteUnaligned(ax), pin.SE3(R, t), f"j{i}")
        pm.appendBodyToJoint(jid, pin.Inertia(mass, c, I), pin.SE3.Identity())
    return m, pm


def panda_urdf() -> Path:
    for base in site.getsitepackages():
        path = Path(base) / "cmeel.prefix/share/example-robot-data/robots/panda_description/urdf/panda.urdf"
        if path.exists():
            return path
    raise FileNotFoundError("example-robot-data's panda.urdf (pip install example-robot-data)")


def panda():
    """The Panda arm from example-robot-data's URDF: the seven revolute joints; the fingers locked
    (fixed) at 0. lagcodegen.urdf.load when it exists, else a few lines of xml.etree here."""
    import numpy as np
    import pinocchio as pin
    path = panda_urdf()
    full = pin.buildModelFromUrdf(str(path))
    fingers = [full.getJointId(name) for name in full.names if "finger" in name]
    pm = pin.buildReducedModel(full, fingers, pin.neutral(full))
    try:
        from lagcodegen import urdf
        m = urdf.load(path, lock=[full.names[j] for j in fingers])
    except (ImportError, TypeError):
        m = _panda_model(path)
    pm.gravity = pin.Motion(np.array([0, 0, -9.81, 0, 0, 0]))
    return m, pm


def _panda_model(path: Path):
    import xml.etree.ElementTree as ET

    import lagcodegen as lcg
    root = ET.parse(path).getroot()

    def origin(el):
        o = el.find("origin") if el is not None else None
        if o is None:
            return (0, 0, 0), (0, 0, 0)
        return (tuple(float(x) for x in o.get("xyz", "0 0 0").split()),
                tuple(float(x) for x in o.get("rpy", "0 0 0").split()))

    inertial = {}
    for link in root.findall("link"):
        el = link.find("inertial")
        if el is None:
            inertial[link.get("name")] = dict(mass=0, com=(0, 0, 0), inertia=(0,) * 6)
            continue
        xyz, rpy = origin(el)
        i = el.find("inertia").attrib
        I = [float(i[k]) for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")]
        if any(rpy):
            import numpy as np
            R = np.array(lcg.Placement(rpy=rpy).rotation.evalf(), dtype=float)
            M = np.array([[I[0], I[3], I[4]], [I[3], I[1], I[5]], [I[4], I[5], I[2]]])
            M = R @ M @ R.T
            I = [M[0, 0], M[1, 1], M[2, 2], M[0, 1], M[0, 2], M[1, 2]]
        inertial[link.get("name")] = dict(mass=float(el.find("mass").get("value")), com=xyz, inertia=tuple(I))
    m = lcg.Model("panda")
    g, = m.parameters(g=9.81)
    m.gravity(g)
    joints = {j.find("child").get("link"): j for j in root.findall("joint")}
    roots = [name for name in inertial if name not in joints]
    order, frontier = [], list(roots)
    while frontier:
        name = frontier.pop(0)
        order.append(name)
        frontier += [c for c, j in joints.items() if j.find("parent").get("link") == name]
    for name in order:
        j = joints.get(name)
        if j is None:
            m.link(name, **inertial[name])
            continue
        xyz, rpy = origin(j)
        kind = j.get("type")
        axis = tuple(float(x) for x in j.find("axis").get("xyz").split()) if j.find("axis") is not None else (1, 0, 0)
        jname = j.get("name")
        if kind in ("revolute", "continuous"):
            joint = lcg.Joint.revolute(jname, axis)
        elif kind == "prismatic" and "finger" not in jname:
            joint = lcg.Joint.prismatic(jname, axis)
        else:
            joint = lcg.Joint.fixed(jname)
        m.link(name, parent=j.find("parent").get("link"), joint=joint, origin=lcg.Placement(xyz, rpy), **inertial[name])
    return m


#: multibody_pin_aba.cpp's joint kinds: Pinocchio's joint model short names -> its code (kinds 0
#: and 1, the unaligned revolute and prismatic joints, take the axis from the model).
PIN_KINDS = {"JointModelRX": 2, "JointModelRY": 3, "JointModelRZ": 4, "JointModelPX": 5, "JointModelPY": 6,
             "JointModelPZ": 7, "JointModelFreeFlyer": 8}


def write_pin_files(pm, states, folder: Path) -> None:
    """The model (after Pinocchio merged fixed links) and the states (q, v pairs in Pinocchio's
    layout) for multibody_pin_aba.cpp, each joint as the kind Pinocchio has it (aligned axes
    stay aligned)."""
    import numpy as np
    lines = []
    for j in range(1, pm.njoints):
        jm = pm.joints[j]
        short = jm.shortname()
        if short in PIN_KINDS:
            kind, ax = PIN_KINDS[short], (0.0, 0.0, 0.0)
        elif short in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
            kind, ax = (0 if "Revolute" in short else 1), tuple(jm.extract().axis)
        else:
            raise ValueError(f"multibody_pin_aba.cpp does not read Pinocchio's {short}")
        X, Y = pm.jointPlacements[j], pm.inertias[j]
        I = Y.inertia
        vals = [*ax, *X.rotation.ravel(), *X.translation, Y.mass, *Y.lever,
                I[0, 0], I[0, 1], I[0, 2], I[1, 1], I[1, 2], I[2, 2]]
        lines.append(f"{pm.parents[j] - 1} {kind} " + " ".join(repr(float(x)) for x in vals))
    (folder / "pin_model.txt").write_text("\n".join(lines) + "\n")
    (folder / "pin_states.txt").write_text("\n".join(" ".join(repr(float(x)) for x in np.r_[q, v]) for q, v in states))


def pin_cpp(out: Path) -> tuple[Path | None, str]:
    """multibody_pin_aba.cpp compiled (or why not)."""
    prefix = next((Path(b) / "cmeel.prefix" for b in site.getsitepackages() if (Path(b) / "cmeel.prefix").exists()), None)
    if prefix is None:
        return None, "no cmeel prefix (pin wheel) found"
    eigen = next((p.parent for b in site.getsitepackages() for p in Path(b).glob("*/include/eigen3/Eigen")), None)
    if eigen is None:
        return None, "the pin wheel ships no Eigen headers and no other Eigen was found"
    exe = out / "pin_aba"
    cmd = ["g++", "-O3", "-DNDEBUG", "-std=c++17", "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS",
           "-DBOOST_MPL_LIMIT_LIST_SIZE=30", "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30", f"-I{prefix / 'include'}",
           f"-I{eigen}", str(HERE / "multibody_pin_aba.cpp"), "-o", str(exe)]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return None, f"g++ failed: {exc}"
    if proc.returncode != 0:
        return None, "g++ failed: " + proc.stderr[-400:]
    return exe, " ".join(cmd[:-3]) + f" (Eigen from {eigen})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", type=Path, default=Path("benchmark-results"))
    ap.add_argument("--sizes", default=None)
    ap.add_argument("--target", type=float, default=0.2, help="seconds per C timing loop")
    ap.add_argument("--pin-exe", type=Path, default=None, help="an already compiled multibody_pin_aba")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")] if args.sizes else ([3, 7] if args.quick else [3, 7, 12, 20, 30])
    args.out.mkdir(parents=True, exist_ok=True)
    load0 = H.load_average()
    if args.pin_exe:
        exe, how = args.pin_exe, f"{args.pin_exe} (given)"
    else:
        H.progress(TAG, "compiling Pinocchio's ABA loop (g++ -O3) ...")
        exe, how = pin_cpp(args.out)
    rows = []
    cache = tempfile.TemporaryDirectory()
    with H.cache_at(Path(cache.name)):  # the model-independent runtime built once, untimed
        H.progress(TAG, "warm-up (the native runtime) ...")
        import lagcodegen as lcg
        lcg.compile_model(lcg.systems.pendulum(), jacobian=False)
    for model in ["panda"] + [f"chain{n}" for n in sizes]:
        H.progress(TAG, f"{model} ...")
        with tempfile.TemporaryDirectory() as tmp, H.cache_at(Path(cache.name)):
            spec = dict(model="panda" if model == "panda" else "chain", n=0 if model == "panda" else int(model[5:]),
                        bench=str(HERE), tmp=tmp, target=args.target)
            start = time.perf_counter()
            proc = subprocess.run([sys.executable, "-c", _ROW, json.dumps(spec)], capture_output=True, text=True,
                                  env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
            wall = time.perf_counter() - start
            line = [ln for ln in proc.stdout.splitlines() if ln.startswith("ROW ")]
            if not line:
                H.progress(TAG, f"{model} failed: {proc.stderr[-2000:]}")
                continue
            row = dict(model=model, wall=wall, **json.loads(line[0][4:]))
            row["cpp_pin"] = None
            if exe is not None and Path(exe).exists():
                r = subprocess.run([str(exe), f"{tmp}/pin_model.txt", f"{tmp}/pin_states.txt", str(args.target)],
                                   capture_output=True, text=True, timeout=600)
                if r.returncode == 0:
                    row["cpp_pin"] = float(r.stdout.split()[0])
            rows.append(row)
            H.progress(TAG, json.dumps(row))
    lines = H.machine_lines("Rigid-body trees against Pinocchio (benchmarks/multibody.py)", (load0, H.load_average()))
    lines.append(f"pinocchio C++ loop: {how if exe else 'not compiled: ' + how}")
    lines.append("")
    head = (f"{'model':8} {'n':>3} {'derive s':>8} {'gen s':>6} {'build s':>7} {'C kB':>6} {'rss MB':>6} {'cc MB':>6} "
            f"{'err':>8} {'C ns':>8} {'pin C++':>8} {'ratio':>6} {'py ns':>8} {'pin py':>8}")
    lines += [head, "-" * len(head)]
    for r in rows:
        cpp = r["cpp_pin"]
        lines.append(f"{r['model']:8} {r['n']:3d} {r['derive']:8.2f} {r['generate']:6.2f} {r['build']:7.2f} "
                     f"{r['c_bytes'] / 1e3:6.1f} {r['rss']:6.0f} {r['cc_rss']:6.0f} {r['err']:8.1e} {r['c_rhs']:8.0f} "
                     f"{cpp if cpp else float('nan'):8.0f} {r['c_rhs'] / cpp if cpp else float('nan'):6.2f} "
                     f"{r['py_lcg']:8.0f} {r['py_pin']:8.0f}")
    text = "\n".join(lines)
    print(text)
    (args.out / "multibody.txt").write_text(text + "\n")
    (args.out / "multibody.json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
