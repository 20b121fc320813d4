"""FMU build time (issue 25): ``lagcodegen.export_fmu`` of the double pendulum's model file, from
the file to the written archive (load, derive, generate, compile, zip), in a new Python process
per measurement (``import lagcodegen`` timed apart, not counted).

Two cases per FMI version, run round-robin ``--rounds`` times (medians) so that machine noise hits
them alike:

* ``warm``: the FMU runtime (core, integrator, FMI functions: compiled once per installation into
  the build cache) already built; the export compiles the model's C and links;
* ``cold``: an empty build cache, so the runtime is compiled too (the first FMU of an installation).

The 1-minute load average is printed before and after. This is a measuring instrument: it asserts
nothing.

Usage::

    python benchmarks/fmu_build.py [--rounds N]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _harness import cpu_model, load_average  # noqa: E402

MODEL = Path(__file__).resolve().parents[1] / "examples" / "double_pendulum.toml"

CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
import lagcodegen
t1 = time.perf_counter()
lagcodegen.export_fmu(sys.argv[1], sys.argv[2], fmi_version=int(sys.argv[3]))
t2 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "export": t2 - t1}))
"""


def measure(version: int, cache: str, folder: str) -> dict:
    env = dict(os.environ, LAGCODEGEN_CACHE=cache)
    out = subprocess.run([sys.executable, "-c", CHILD, str(MODEL), os.path.join(folder, f"dp{version}.fmu"),
                          str(version)], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    print(f"CPU: {cpu_model()}, {os.cpu_count()} cores; load average before: {load_average()}")
    times: dict[tuple[int, str], list[float]] = {}
    imports: list[float] = []
    with tempfile.TemporaryDirectory() as folder:
        warm = os.path.join(folder, "warm-cache")
        for version in (2, 3):  # fill the warm cache
            measure(version, warm, folder)
        for r in range(args.rounds):
            for version in (2, 3):
                for case in ("warm", "cold"):
                    cache = warm if case == "warm" else tempfile.mkdtemp(dir=folder, prefix="cold-")
                    m = measure(version, cache, folder)
                    times.setdefault((version, case), []).append(m["export"])
                    imports.append(m["import"])
    print(f"double pendulum, export_fmu (file -> .fmu), median of {args.rounds} rounds, seconds:")
    for (version, case), values in sorted(times.items()):
        print(f"  FMI {version}.0 {case:4s}  {statistics.median(values):.3f}   (min {min(values):.3f}, "
              f"max {max(values):.3f})")
    print(f"  import lagcodegen (not counted): median {statistics.median(imports):.3f}")
    print(f"load average after: {load_average()}")


if __name__ == "__main__":
    main()
