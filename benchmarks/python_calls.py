"""Forward dynamics per call from Python (issue 38): ``CompiledModel.rhs`` against Pinocchio's
``pin.aba`` on robots read from example-robot-data's URDFs (the double pendulum, the UR5; fixed
base), the same state for both.

Each round times a block of calls of every contender in turn (interleaved, so that the load of a
busy machine falls on all alike), and the ratio to ``pin.aba`` is taken per round; the table gives
the median ns per call, the median ratio and its spread (25th-75th percentile over the rounds),
with the 1-minute load before and after, and the ratio of the fastest rounds (min / min: the
least disturbed by other processes on a loaded machine). The contenders:

* ``rhs``: ``cm.rhs(0.0, y)``, a new array (q', v') returned: the call a scipy integrator or a
  controller makes;
* ``rhs out=``: ``cm.rhs(0.0, y, out=buf)``, into a caller's array;
* ``C call``: the runtime's ``lcg_rhs_call`` through cffi with pointers made once (no checks, no
  allocation): the floor of any cffi binding, for scale;
* ``pin.aba``: ``pin.aba(model, data, q, v, tau)`` (v' only; the URDF's joint damping as the
  torques -d v, as lagcodegen models it).

The accelerations are checked against Pinocchio's at the timed state (max relative difference).
This is a measuring instrument: it asserts nothing about the numbers it reports.

Usage::

    python benchmarks/python_calls.py [--quick] [--rounds 501] [--block 200] [--out DIR]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

TAG = "python_calls"
ROBOTS = {"double_pendulum": "double_pendulum_description/urdf/double_pendulum.urdf",
          "ur5": "ur_description/urdf/ur5_robot.urdf"}


def robots_folder() -> Path:
    import pinocchio as pin
    return Path(pin.__file__).resolve().parents[4] / "share" / "example-robot-data" / "robots"


def contenders(name: str):
    """(the contenders by label, the relative error of v' against pin.aba, nv) for robot ``name``."""
    import pinocchio as pin
    import lagcodegen as lcg
    file = robots_folder() / ROBOTS[name]
    cm = lcg.compile_model(lcg.urdf.load(file))
    pm = pin.buildModelFromUrdf(str(file))
    data = pm.createData()
    names = [pm.names[j] for j in range(1, pm.njoints)]
    if cm.state_names[:cm.nq] != names:
        raise RuntimeError(f"{name}: joint order differs ({cm.state_names[:cm.nq]} against {names})")
    rng = np.random.default_rng(0)
    q, v = rng.uniform(-1, 1, pm.nq), rng.normal(size=pm.nv)
    tau = -np.asarray(pm.damping) * v
    y = np.r_[q, v, np.zeros(cm.ny - pm.nq - pm.nv)]
    ref = pin.aba(pm, data, q, v, tau)
    err = float(np.abs(cm.rhs(0.0, y)[cm.nq:cm.nq + cm.nv] - ref).max() / np.abs(ref).max())
    buf = np.empty(cm.ny)
    fb = cm.ffi.from_buffer
    yp, op, pp, table = fb("double[]", y), fb("double[]", np.empty(cm.ny)), cm._default_ptr, cm.table
    fns = {"rhs": lambda: cm.rhs(0.0, y), "rhs out=": lambda: cm.rhs(0.0, y, out=buf)}
    call = getattr(cm.lib, "lcg_rhs_call", None)  # (absent from lagcodegen before 2026-12-06: not timed)
    if call is not None:
        fns["C call"] = lambda: call(table, 0.0, yp, pp, op)
    fns["pin.aba"] = lambda: pin.aba(pm, data, q, v, tau)
    return fns, err, pm.nv


def interleaved(fns: dict, rounds: int, block: int) -> dict[str, list[float]]:
    """ns per call of each function, one sample per round, the functions in turn within a round."""
    samples = {k: [] for k in fns}
    for _ in range(rounds):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            for _ in range(block):
                fn()
            samples[k].append((time.perf_counter() - t0) / block * 1e9)
    return samples


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="51 rounds of 200 calls")
    ap.add_argument("--rounds", type=int, default=501)
    ap.add_argument("--block", type=int, default=200)
    ap.add_argument("--out", type=Path, help="also write the table to OUT/python_calls.txt")
    args = ap.parse_args(argv)
    rounds, block = (51, 200) if args.quick else (args.rounds, args.block)
    load0 = H.load_average()
    lines = [f"{rounds} interleaved rounds of {block} calls; ratio = per-round time / pin.aba's",
             f"{'robot':<16}{'nv':>3}  {'contender':<10}{'ns/call':>9}{'ratio':>7}{'q25-q75':>13}{'min ns':>8}"
             f"{'min/min':>8}{'rel err':>10}"]
    try:
        for name in ROBOTS:
            H.progress(TAG, f"{name} ...")
            fns, err, nv = contenders(name)
            samples = interleaved(fns, rounds, block)
            ref = samples["pin.aba"]
            for k, s in samples.items():
                ratios = [a / b for a, b in zip(s, ref)]
                q25, q75 = np.percentile(ratios, [25, 75])
                lines.append(f"{name:<16}{nv:>3}  {k:<10}{statistics.median(s):>9.0f}{statistics.median(ratios):>7.2f}"
                             f"{q25:>7.2f}-{q75:<5.2f}{min(s):>8.0f}{min(s) / min(ref):>8.2f}"
                             f"{err if k == 'rhs' else float('nan'):>10.1e}")
    except ImportError:
        lines.append("Pinocchio is not installed (pip install pin example-robot-data): not measured")
    text = "\n".join(H.machine_lines("rhs from Python against pin.aba (benchmarks/python_calls.py)",
                                     (load0, H.load_average())) + [""] + lines)
    print(text)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "python_calls.txt").write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
