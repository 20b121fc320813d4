"""Model files and Models to compiled models in a new Python process, the pipeline cache warm and
cold (issue 38's pipeline cache beyond URDF: ``compile_file`` and ``compile_model``).

Rows, each a new process (``python -c``), ``import lagcodegen`` timed apart:

* ``warm``: the model already in the cache (an untimed process filled it): its generated code is
  read and its library loaded, nothing derived or generated;
* ``cold model``: the same model under a name never used before (another cache key, other C):
  derive, generate and compile the model's C (the runtime already in the cache).

Models: the bundled ``examples/double_pendulum.toml``, ``examples/cartesian_pendulum.toml``
(constrained: index 1) and the 6-joint ``examples/ur_like_arm.urdf`` through ``compile_file``,
and 5- and 10-link pendulums built in Python (:func:`lagcodegen.model.systems.n_link_pendulum`)
through ``compile_model`` (``--quick``: 5 only). Each process checks what it got: for
the warm rows that nothing was derived (``stored_scene(code) is None``). Medians over
``--rounds`` rounds, contenders round-robin; the load average is printed. A measuring
instrument: it asserts nothing about the times.

Usage::

    python benchmarks/model_cache.py [--quick] [--rounds N] [--out DIR]
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

TAG = "model_cache"
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

SCRIPT = r"""
import json, sys, time
t0 = time.perf_counter()
import lagcodegen as lcg
from lagcodegen.codegen.record import stored_scene
t1 = time.perf_counter()
kind, source = sys.argv[1], sys.argv[2]
if kind == "file":
    sim = lcg.compile_file(source)
else:
    from lagcodegen.model.systems import n_link_pendulum
    n, name = source.split(":")
    sim = lcg.compile_model(n_link_pendulum(int(n), name=name))
t2 = time.perf_counter()
code = getattr(sim, "compiled", sim).code
print(json.dumps(dict(imports=t1 - t0, build=t2 - t1, derived=stored_scene(code) is not None)))
"""


def run(kind: str, source: str, cache: Path) -> dict:
    env = {**os.environ, "LAGCODEGEN_CACHE": str(cache)}
    proc = subprocess.run([sys.executable, "-c", SCRIPT, kind, source], capture_output=True, text=True, env=env,
                          timeout=1800)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-2000:])
    return json.loads(proc.stdout.strip().splitlines()[-1])


def variant(name: str, folder: Path, suffix: str = ".toml") -> str:
    """A copy of examples/<name><suffix> under another model name: a new cache key and new C to compile."""
    text = (EXAMPLES / f"{name}{suffix}").read_text()
    other = f"{name}_{uuid.uuid4().hex[:8]}"
    path = folder / f"{other}{suffix}"
    named = (f'<robot name="{name}"', f'<robot name="{other}"') if suffix == ".urdf" else \
        (f'name = "{name}"', f'name = "{other}"')
    assert named[0] in text, named[0]
    path.write_text(text.replace(*named, 1))
    return str(path)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="2 rounds, no 10-link pendulum")
    ap.add_argument("--rounds", type=int, default=None)
    ap.add_argument("--out", type=Path, default=Path("out") / TAG)
    args = ap.parse_args(argv)
    rounds = args.rounds or (2 if args.quick else 3)
    args.out.mkdir(parents=True, exist_ok=True)
    load_before = H.load_average()
    cache = Path(tempfile.mkdtemp(prefix="lcg-model-cache-"))
    folder = Path(tempfile.mkdtemp(prefix="lcg-model-files-"))
    models = {"double_pendulum.toml": ("file", lambda: str(EXAMPLES / "double_pendulum.toml"),
                                       lambda: variant("double_pendulum", folder)),
              "cartesian_pendulum.toml": ("file", lambda: str(EXAMPLES / "cartesian_pendulum.toml"),
                                          lambda: variant("cartesian_pendulum", folder))}
    models["ur_like_arm.urdf (compile_file)"] = ("file", lambda: str(EXAMPLES / "ur_like_arm.urdf"),
                                                 lambda: variant("ur_like_arm", folder, ".urdf"))
    for n in (5,) if args.quick else (5, 10):
        models[f"{n}-link pendulum (Model)"] = ("model", lambda n=n: f"{n}:chain{n}",
                                                lambda n=n: f"{n}:chain{n}_{uuid.uuid4().hex[:8]}")
    H.progress(TAG, "building the runtime and filling the cache (untimed)")
    for kind, warm, _ in models.values():
        run(kind, warm(), cache)
    samples: dict = {}
    for r in range(rounds):
        for name, (kind, warm, cold) in models.items():
            H.progress(TAG, f"round {r + 1}/{rounds}: {name}")
            samples.setdefault((name, "warm"), []).append(run(kind, warm(), cache))
            samples.setdefault((name, "cold model"), []).append(run(kind, cold(), cache))
    rows = []
    for (name, row), runs in samples.items():
        rows.append(dict(model=name, row=row, build_s=statistics.median(s["build"] for s in runs),
                         imports_s=statistics.median(s["imports"] for s in runs),
                         derived=any(s["derived"] for s in runs)))
    for name in models:
        warm = next(r for r in rows if r["model"] == name and r["row"] == "warm")
        cold = next(r for r in rows if r["model"] == name and r["row"] == "cold model")
        warm["speedup"] = cold["build_s"] / warm["build_s"]
    cols = [("model", "model", "{}"), ("row", "cache", "{}"), ("build_s", "compile [s]", "{:.3f}"),
            ("imports_s", "import [s]", "{:.3f}"), ("derived", "derived", "{}"), ("speedup", "cold/warm", "{:.1f}")]
    text = "\n".join(H.machine_lines("model files and Models in a new process (pipeline cache)",
                                     (load_before, H.load_average()))
                     + ["", f"medians of {rounds} rounds; compile = compile_file / compile_model to a compiled model, "
                        "`import lagcodegen` excluded (its own column)", "", H.format_table(cols, rows)])
    print(text)
    H.write_report(args.out, TAG, text, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
