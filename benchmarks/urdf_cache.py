"""URDF to compiled model in a new Python process (issue 38's first target): ``compile_urdf``
of example-robot-data's UR5 and Talos, with the pipeline cache warm and cold.

Rows, each a new process (``python -c``), ``import lagcodegen`` timed apart:

* ``warm``: ``lcg.compile_urdf(path)`` with the model already in the cache (an untimed process
  filled it): the cached code is read and its library loaded, nothing derived (target: UR5
  <= 0.3 s, Talos <= 1 s);
* ``cold model``: the same with a prefix never used before (another cache key): derive, generate
  and compile the model's C; the runtime (the model-independent CVODE/IDA drivers, built once per
  installation) already in the cache (target: UR5 <= 2 s); ``cold model (fill)``: the one run
  that filled the warm cache (the same work, one sample; Talos's only cold figure);
* ``empty cache``: a fresh, empty LAGCODEGEN_CACHE folder, so the runtime is built too (what the
  very first model of an installation costs; no target);
* ``warm, limits``: ``compile_urdf(path, load={"limits": True})`` (the constrained system on the
  impact driver) from a warm cache.

Each process checks what it got (the model's coordinate count, and for the warm rows that nothing
was derived: ``stored_scene(code) is None``). Medians over ``--rounds`` rounds, contenders round-robin;
the load average is printed. This is a measuring instrument: it asserts nothing about the times.

Usage::

    python benchmarks/urdf_cache.py [--quick] [--rounds N] [--robots ur5,talos] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import uuid
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

TAG = "urdf_cache"

ROBOTS = {"ur5": "ur_description/urdf/ur5_robot.urdf", "talos": "talos_data/robots/talos_full_v2.urdf",
          "panda": "panda_description/urdf/panda.urdf"}

#: Targets of issue 38 in seconds, by (robot, row).
TARGETS = {("ur5", "warm"): 0.3, ("talos", "warm"): 1.0, ("ur5", "cold model"): 2.0,
           ("ur5", "cold model (fill)"): 2.0}

SCRIPT = r"""
import json, sys, time
t0 = time.perf_counter()
import lagcodegen as lcg
from lagcodegen.codegen.record import stored_scene
t1 = time.perf_counter()
path, prefix, limits = sys.argv[1], sys.argv[2] or None, sys.argv[3] == "1"
sim = lcg.compile_urdf(path, prefix=prefix, load={"limits": True} if limits else None)
t2 = time.perf_counter()
code = sim.compiled.code if hasattr(sim, "compiled") else sim.code  # a constrained system's, a model's
n = len(sim.state_names) // 2 if hasattr(sim, "state_names") else -1
print(json.dumps(dict(imports=t1 - t0, build=t2 - t1, n=n, derived=stored_scene(code) is not None)))
"""


def robot_path(name: str) -> Path:
    """example-robot-data's URDF of ``name`` (installed with Pinocchio under the cmeel prefix)."""
    for base in sys.path:
        path = Path(base) / "cmeel.prefix/share/example-robot-data/robots" / ROBOTS[name]
        if path.is_file():
            return path
    raise FileNotFoundError(f"example-robot-data's {ROBOTS[name]} (pip install example-robot-data)")


def run(path: Path, cache: Path, prefix: str = "", limits: bool = False) -> dict:
    env = {**os.environ, "LAGCODEGEN_CACHE": str(cache)}
    proc = subprocess.run([sys.executable, "-c", SCRIPT, str(path), prefix, "1" if limits else "0"],
                          capture_output=True, text=True, env=env, timeout=1800)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-2000:])
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="the UR5 only, 2 rounds, no empty-cache row")
    ap.add_argument("--rounds", type=int, default=None)
    ap.add_argument("--robots", default=None, help="comma-separated: ur5, talos, panda (default ur5,talos)")
    ap.add_argument("--out", type=Path, default=Path("out") / TAG)
    args = ap.parse_args(argv)
    rounds = args.rounds or (2 if args.quick else 3)
    robots = (args.robots or ("ur5" if args.quick else "ur5,talos")).split(",")
    args.out.mkdir(parents=True, exist_ok=True)
    load_before = H.load_average()
    warm = Path(tempfile.mkdtemp(prefix="lcg-urdf-warm-"))
    H.progress(TAG, "building the runtime into the warm cache (untimed)")
    run(robot_path(robots[0]), warm, "warmup_" + uuid.uuid4().hex[:8])
    contenders = {}
    samples: dict = {}
    for robot in robots:
        path = robot_path(robot)
        H.progress(TAG, f"{robot}: filling the warm cache (one cold run each, reported as 'fill')")
        samples[(robot, "cold model (fill)")] = [run(path, warm)]
        samples[(robot, "cold model (fill), limits")] = [run(path, warm, limits=True)]
        contenders[(robot, "warm")] = lambda path=path: run(path, warm)
        contenders[(robot, "warm, limits")] = lambda path=path: run(path, warm, limits=True)
        if robot != "talos":  # Talos's cold build is the fill's (one run: tens of seconds)
            contenders[(robot, "cold model")] = lambda path=path: run(path, warm, "c" + uuid.uuid4().hex[:10])
        if not args.quick and robot == "ur5":
            contenders[(robot, "empty cache")] = lambda path=path: run(
                path, Path(tempfile.mkdtemp(prefix="lcg-urdf-empty-")))
    for r in range(rounds):
        for key, fn in contenders.items():
            H.progress(TAG, f"round {r + 1}/{rounds}: {key[0]}, {key[1]}")
            samples.setdefault(key, []).append(fn())
    rows = []
    for (robot, kind), runs in samples.items():
        target = TARGETS.get((robot, kind))
        build = statistics.median(s["build"] for s in runs)
        rows.append(dict(robot=robot, row=kind, build_s=build, imports_s=statistics.median(s["imports"] for s in runs),
                         n=runs[0]["n"], derived=any(s["derived"] for s in runs),
                         target=target, met=None if target is None else ("yes" if build <= target else "NO")))
    cols = [("robot", "robot", "{}"), ("row", "cache", "{}"), ("n", "coords", "{}"),
            ("build_s", "compile_urdf [s]", "{:.3f}"), ("imports_s", "import [s]", "{:.3f}"),
            ("derived", "derived", "{}"), ("target", "target [s]", "{}"), ("met", "met", "{}")]
    text = "\n".join(H.machine_lines("compile_urdf in a new process (issue 38)", (load_before, H.load_average()))
                     + ["", f"medians of {rounds} rounds; compile_urdf = URDF file to compiled model, "
                        "`import lagcodegen` excluded (its own column)", "", H.format_table(cols, rows)])
    print(text)
    H.write_report(args.out, TAG, text, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
