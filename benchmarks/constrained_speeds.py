"""Figures of constrained systems with generalized speeds (issue 37): a pinned body on a quaternion
free joint against the same system in Z-Y-X angles, a dropped body's bounce apex against e^2 h,
a tilted body's impacts against Z-Y-X, and Solo12 (free flyer, PD joints, four frictionless foot
contacts) landing and resting with its contact forces against m g. The systems are the tests'
(tests/test_constrained_speeds.py).

    PYTHONPATH=. python benchmarks/constrained_speeds.py
"""
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import lagcodegen as lcg  # noqa: E402
import test_constrained_speeds as T  # noqa: E402
from lagcodegen.theory.constraints import ConstrainedSystem  # noqa: E402

rb, w = np.array([0.1, 0.2, 0.5]), np.array([0.7, -1.1, 2.3])
quat = lcg.compile_constrained(T.pinned_body("quaternion", rb)); euler = lcg.compile_constrained(T.pinned_body("ZYX", rb))
vlin = -np.cross(w, rb); t = np.linspace(0, 3, 301)
rq = quat.simulate(t, np.r_[-rb, 0, 0, 0, 1], np.r_[vlin, w], rtol=1e-11, atol=1e-12)
rz = euler.simulate(t, np.r_[-rb, 0, 0, 0], np.r_[vlin, w[::-1]], rtol=1e-11, atol=1e-12)
print("pinned body: |x_quat - x_ZYX| max", np.abs(rq.y[:, :3] - rz.y[:, :3]).max(), "| |q|-1 | max", np.abs(np.linalg.norm(rq.y[:, 3:7], axis=1) - 1).max(), "energy ptp", np.ptp(rq["energy"]))
e, h, r, yaw, wz = 0.6, 0.4, 0.1, 0.7, 3.0
sim = lcg.compile_constrained(T.dropped_box("quaternion", (0, 0, -r), e))
t1 = np.sqrt(2 * h / 9.81)
res = sim.simulate(np.array([0.0, 0.5 * t1, t1 * (1 + e)]), [0, 0, h + r, 0, 0, np.sin(yaw / 2), np.cos(yaw / 2)], [0, 0, 0, 0, 0, wz], rtol=1e-12, atol=1e-13)
print("bounce apex: z_c - e^2 h =", res.y[-1, 2] - r - e * e * h, "v_z at apex", res.y[-1, 9], "impact t - t1", res.impacts[0].t - t1)
quat = lcg.compile_constrained(T.dropped_box("quaternion", (0.1, 0.05, -0.1), 0.5)); euler = lcg.compile_constrained(T.dropped_box("ZYX", (0.1, 0.05, -0.1), 0.5))
t = np.linspace(0, 0.6, 61); ang = (0.3, 0.4, -0.2)
rq = quat.simulate(t, np.r_[0, 0, 0.5, T.zyx_quaternion(*ang)], np.zeros(6), rtol=1e-11, atol=1e-12)
rz = euler.simulate(t, np.r_[0, 0, 0.5, ang], np.zeros(6), rtol=1e-11, atol=1e-12)
print("tilted box: impacts", len(rq.impacts), [r.kind for r in rq.impacts][:6], "|x_quat - x_ZYX| max", np.abs(rq.y[:, :3] - rz.y[:, :3]).max(),
      "impulse diff", max(abs(a.impulse - b.impulse) for a, b in zip(rq.impacts, rz.impacts)))

import pinocchio as pin  # noqa: E402
from lagcodegen.modelfile import urdf  # noqa: E402

F = (Path(pin.__file__).resolve().parents[4] / "share" / "example-robot-data" / "robots" / "solo_description" / "robots"
     / "solo12.urdf")
feet = {j.find("parent").get("link"): [float(x) for x in j.find("origin").get("xyz").split()]
        for j in ET.parse(F).getroot().findall("joint") if j.find("child").get("link").endswith("_FOOT")}
pose = {}
for leg in ("FL", "FR", "HL", "HR"):
    front = leg[0] == "F"
    pose.update({f"{leg}_HAA": 0.0, f"{leg}_HFE": 0.8 if front else -0.8, f"{leg}_KFE": -1.6 if front else 1.6})
t0 = time.perf_counter()
m = urdf.load(F, floating=True)
for name, ref in pose.items():
    q = m.coords[m.index(name)]
    m.generalized_force(q, -20.0 * (q - ref) - 0.5 * m.dot(q))
solo = lcg.compile_constrained(ConstrainedSystem(m, inequalities=[lcg.ground_contact(m, link, xyz, restitution=0.0)
                                                                  for link, xyz in feet.items()]))
build = time.perf_counter() - t0
q0 = np.array(m.neutral())
for name, ref in pose.items():
    q0[m.index(name)] = ref
q0[2] = 0.3
t0 = time.perf_counter()
res = solo.simulate(np.linspace(0, 3.0, 61), q0, np.zeros(m.nv), rtol=1e-8, atol=1e-10, method="bdf")
run = time.perf_counter() - t0
weight = pin.computeTotalMass(pin.buildModelFromUrdf(str(F), pin.JointModelFreeFlyer())) * 9.81
normal = sum(res[f"lambda_ineq_{k}"][-1] for k in range(4))
print(f"solo12: build {build:.2f} s (cached code counts as built), run 3 s in {run:.2f} s, {res.stats['steps']} steps; "
      f"contacts {[(r.kind, round(r.t, 4)) for r in res.impacts]}; sum lambda / m g - 1 = {normal / weight - 1:.2e}; "
      f"|v| max at 3 s {np.abs(res.y[-1, m.nq:]).max():.2e}; base x, y at 3 s {res.y[-1, :2]}")
