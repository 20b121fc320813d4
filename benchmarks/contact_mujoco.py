"""Solo12 dropped on the ground: lagcodegen's event-driven contact (impacts, persistent contact,
Coulomb friction on the exact circular cone) against MuJoCo's soft contact with stiff settings
(issue 39), on what both should agree on: landing time, final standing base height, total normal
contact force at rest, and (mu = 0.2, where the feet slip apart after landing) the feet's final
spread (their mean horizontal distance from their centroid).

The system is the tests' (tests/test_constrained_speeds.py: ``solo12_on_the_ground``): Solo12
from example-robot-data on a free flyer, its 12 joints held by PD torques -20 (q - q_ref) - 0.5 q'
about a standing posture, point contacts at the four feet (the URDF's foot frames on the lower
legs), restitution 0, dropped with its base at 0.3 m; friction mu = 1, mu = 0.2 (the four feet slip together
after landing, then grip) and frictionless.

MuJoCo (``pip install mujoco``, DeepMind's binary package) loads the same URDF with its visual and
collision meshes stripped; the base gets a free joint, each lower leg a sphere of radius R centred
on its foot point and the floor plane sits at z = -R, so that a sphere touches where the foot
point reaches z = 0. The PD torques are MuJoCo joint stiffness (springref q_ref) and damping, the
joint limits (+-10 rad in the URDF) are off, friction mu on the elliptic (circular) cone with
condim 3, contacts stiff: solref (2 dt, 1) (critically damped, the stiffest MuJoCo accepts at the
step dt), solimp (0.99, 0.999, 0.001), the implicitfast integrator. MuJoCo's landing time is
the time of the first state in which its collision detection finds a contact (a multiple of dt).

    PYTHONPATH=. python benchmarks/contact_mujoco.py [--quick] [--out DIR]

--quick: MuJoCo at dt = 2e-4 (otherwise 1e-4 and 5e-5), friction mu = 1 and 0.2 only.
"""

from __future__ import annotations

import argparse
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

T_END = 3.0  # s: both runs; at rest well before
RADIUS = 1e-3  # m: MuJoCo's foot spheres
G = 9.81


def lagcodegen_run(friction):
    """Build and run the tests' system; (figures, build s, run s)."""
    import test_constrained_speeds as T  # the tests' system

    t0 = time.perf_counter()
    m, sim, q0 = T.solo12_on_the_ground(friction=friction)
    build = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = sim.simulate(np.linspace(0.0, T_END, 61), q0, np.zeros(m.nv), rtol=1e-8, atol=1e-10, method="bdf")
    run = time.perf_counter() - t0
    land = min(r.t for r in res.impacts if r.kind in ("stick", "bounce"))
    normal = sum(res[f"lambda_ineq_{k}"][-1] for k in range(4))
    slips = len(res.impacts.transitions()) if friction is not None else None
    return {"land": land, "height": res.y[-1, 2], "normal": normal, "speed": np.abs(res.y[-1, m.nq:]).max(),
            "spread": spread(T.solo12_feet_world(m)(res.y[-1])), "slips": slips,
            "steps": res.stats.get("steps")}, build, run


def spread(feet):
    """The feet's mean horizontal distance from their centroid (feet: 4 x 3 world positions)."""
    xy = np.asarray(feet)[:, :2]
    return float(np.linalg.norm(xy - xy.mean(axis=0), axis=1).mean())


def mujoco_model(mujoco, path, feet, friction, dt):
    """The MuJoCo model of the same system (see the module's text)."""
    root = ET.parse(path).getroot()
    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for el in link.findall(tag):
                link.remove(el)
    spec = mujoco.MjSpec.from_string(ET.tostring(root, encoding="unicode"))
    spec.option.timestep = dt
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.worldbody.first_body().add_freejoint()
    mu = 0.0 if friction is None else friction
    condim = 1 if friction is None else 3

    def contact(g):
        g.condim = condim
        g.friction = [mu, 0.0, 0.0]
        g.solref = [2 * dt, 1.0]
        g.solimp = [0.99, 0.999, 0.001, 0.5, 2.0]

    for body in spec.bodies:
        if body.name in feet:
            g = body.add_geom()
            g.type = mujoco.mjtGeom.mjGEOM_SPHERE
            g.size = [RADIUS, 0, 0]
            g.pos = feet[body.name]
            g.mass = 0.0
            contact(g)
    plane = spec.worldbody.add_geom()
    plane.type = mujoco.mjtGeom.mjGEOM_PLANE
    plane.size = [5, 5, 0.1]
    plane.pos = [0, 0, -RADIUS]
    contact(plane)
    model = spec.compile()
    model.jnt_limited[:] = 0
    return model


def mujoco_run(mujoco, path, feet, pose, friction, dt):
    """(figures, run s) of MuJoCo's drop."""
    model = mujoco_model(mujoco, path, feet, friction, dt)
    data = mujoco.MjData(model)
    for name, ref in pose.items():
        j = model.joint(name)
        data.qpos[j.qposadr[0]] = ref
        model.jnt_stiffness[j.id] = 20.0
        model.qpos_spring[j.qposadr[0]] = ref
        model.dof_damping[j.dofadr[0]] = 0.5
    data.qpos[2] = 0.3
    data.qpos[3:7] = [1, 0, 0, 0]
    land = None
    t0 = time.perf_counter()
    steps = int(round(T_END / dt))
    for _ in range(steps):
        before = data.time
        mujoco.mj_step(model, data)  # its collision detection runs on the state at the step's start
        if land is None and data.ncon > 0:
            land = before  # the first state MuJoCo finds in contact
    run = time.perf_counter() - t0
    f6, normal = np.zeros(6), 0.0
    for i in range(data.ncon):
        mujoco.mj_contactForce(model, data, i, f6)
        normal += f6[0]
    balls = [data.geom_xpos[i] for i in range(model.ngeom) if model.geom_type[i] == mujoco.mjtGeom.mjGEOM_SPHERE]
    return {"land": land, "height": data.qpos[2], "normal": normal, "speed": np.abs(data.qvel).max(),
            "spread": spread(balls), "contacts": data.ncon, "mass": model.body_subtreemass[0]}, run


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="MuJoCo at dt = 2e-4 only, friction mu = 1 and 0.2 only")
    ap.add_argument("--out", type=Path, help="also write the table to OUT/contact_mujoco.txt")
    args = ap.parse_args(argv)
    load0 = H.load_average()
    lines = []
    try:
        import pinocchio as pin

        import test_constrained_speeds as T
    except ImportError:
        lines.append("Pinocchio is not installed (pip install pin example-robot-data): Solo12 not measured")
        pin = None
    try:
        import mujoco
        if not hasattr(mujoco, "MjSpec") or not hasattr(mujoco, "mj_step"):
            raise ImportError(f"the module 'mujoco' {getattr(mujoco, '__version__', '?')} is not DeepMind's "
                              "simulator (no MjSpec / mj_step)")
    except ImportError as exc:
        lines.append(f"MuJoCo is not usable ({exc}): pip install mujoco (DeepMind's binary package, 3.x)")
        mujoco = None
    if pin is not None:
        path = T.solo12_path()
        feet = T.solo12_feet(path)
        weight = pin.computeTotalMass(pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())) * G
        if mujoco is not None:
            lines.append(f"MuJoCo {mujoco.__version__}; Solo12 weight m g = {weight:.9g} N (Pinocchio's mass)")
        frictions = [1.0, 0.2] if args.quick else [1.0, 0.2, None]
        steps = [2e-4] if args.quick else [1e-4, 5e-5]
        rows = []
        for friction in frictions:
            label = "frictionless" if friction is None else f"mu = {friction:g}"
            H.progress("contact_mujoco", f"lagcodegen, {label}")
            ours, build, run = lagcodegen_run(friction)
            rows.append((label, "lagcodegen (events)", ours, f"build {build:.1f} s, run {run:.2f} s"))
            for dt in steps if mujoco is not None else []:
                H.progress("contact_mujoco", f"MuJoCo, {label}, dt = {dt:g}")
                theirs, mrun = mujoco_run(mujoco, path, feet, T.SOLO12_POSE, friction, dt)
                rows.append((label, f"MuJoCo dt = {dt:g}", theirs, f"run {mrun:.2f} s ({int(round(T_END / dt))} steps)"))
                rel = {key: abs(theirs[key] / ours[key] - 1) for key in ("land", "height", "normal", "spread")}
                ok = all(v <= 0.01 for v in rel.values())
                lines.append(f"{label}, MuJoCo dt = {dt:g} vs lagcodegen: landing time {rel['land']:.2e}, standing "
                             f"height {rel['height']:.2e}, total normal force {rel['normal']:.2e}, feet's spread "
                             f"{rel['spread']:.2e} relative ({'all within' if ok else 'NOT all within'} the 1% target)")
        table = [f"{'case':<14} {'run':<22} {'landing s':>12} {'base z m':>12} {'sum N / mg - 1':>15} "
                 f"{'spread m':>10} {'max |v|':>9}  time"]
        for label, who, fig, cost in rows:
            table.append(f"{label:<14} {who:<22} {fig['land']:>12.6f} {fig['height']:>12.7f} "
                         f"{fig['normal'] / weight - 1:>15.2e} {fig['spread']:>10.6f} {fig['speed']:>9.1e}  {cost}")
        lines = table + [""] + lines
        for label, who, fig, _ in rows:
            if who.startswith("lagcodegen") and fig["slips"] is not None:
                lines.append(f"lagcodegen with {label}: {fig['slips']} stick/slip transitions after landing"
                             + (" (no foot slips)" if fig["slips"] == 0 else ""))
    text = "\n".join(H.machine_lines("Solo12 drop: lagcodegen vs MuJoCo", (load0, H.load_average())) + [""] + lines)
    print(text)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "contact_mujoco.txt").write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
