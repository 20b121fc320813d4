"""Time to a first answer (issue 14): a model never built before, from its description to the
first simulated trajectory, in a new Python process.

For the pendulum (n = 1) and the double pendulum (n = 2), t in [0, 10], rtol 1e-8, atol 1e-10:

* ``lagcodegen``: ``compile_model`` (derive, generate, compile the model's own C into a library
  for the model-independent runtime, load) and the first ``simulate`` of a model whose code was
  never compiled (a fresh prefix), the runtime (the native CVODE driver, built once per
  installation) already in the cache;
* ``lagcodegen, empty cache``: the same with an empty cache, so the runtime is built too (what the
  very first model of an installation costs);
* ``lagcodegen index-1`` / ``lagcodegen GGL`` (row n = 2 only): ``compile_constrained`` of a
  pendulum in Cartesian coordinates (x, y with x^2 + y^2 = l^2; 2 coordinates, 1 constraint) and
  its first ``simulate`` (CVODE on the index-1 form, IDA on the GGL form), a model never built, the
  runtime (which holds the constrained drivers too) in the cache; no CasADi counterpart;
* ``casadi``: the same Lagrangian derived with CasADi's SX (M = d2T/dq'dq', F from the Euler-
  Lagrange equations, M q'' = F solved by ``solve``), ``integrator("cvodes")`` built and called once.

Every measurement is a new process; the imports (``import lagcodegen``, ``import casadi``) are
timed apart and reported in their own column, not counted in the first answer. The contenders
run round-robin, ``--rounds`` times (medians), so that machine noise hits them alike; the
load average is printed. This is a measuring instrument: it asserts nothing.

Usage::

    python benchmarks/first_answer.py [--quick] [--rounds N] [--out DIR]
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
import _harness as H  # noqa: E402

TAG = "first_answer"

LAGCODEGEN = r"""
import json, sys, time, uuid
t0 = time.perf_counter()
import lagcodegen as lcg
t1 = time.perf_counter()
n = int(sys.argv[1])
model = lcg.systems.pendulum() if n == 1 else lcg.systems.double_pendulum()
sim = lcg.compile_model(model, prefix="fa_" + uuid.uuid4().hex[:12])
t2 = time.perf_counter()
res = sim.simulate([0.0, 10.0], q0=[1.0] * n, rtol=1e-8, atol=1e-10)
t3 = time.perf_counter()
assert res.status == 0, res.message
print(json.dumps(dict(imports=t1 - t0, build=t2 - t1, first=t3 - t1, y=float(res.y[-1, 0]), cached=sim.cached)))
"""

CONSTRAINED = r"""
import json, sys, time, uuid
t0 = time.perf_counter()
import math
import lagcodegen as lcg
from lagcodegen.theory.constraints import ConstrainedSystem
t1 = time.perf_counter()
form = sys.argv[2]
m = lcg.Model("fa_" + uuid.uuid4().hex[:12])
x, y = m.coordinates("x y")
l, g, mass = m.parameters(l=1.0, g=9.81, m=1.0)
m.particle("bob", mass, (x, y))
m.gravity(g)
sim = lcg.compile_constrained(ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - l ** 2]), form)
t2 = time.perf_counter()
res = sim.simulate([0.0, 10.0], q0=[math.sin(1.0), -math.cos(1.0)], v0=[0.0, 0.0], rtol=1e-8, atol=1e-10)
t3 = time.perf_counter()
assert res.status == 0, res.message
print(json.dumps(dict(imports=t1 - t0, build=t2 - t1, first=t3 - t1, y=float(res.y[-1, 0]), cached=False)))
"""

#: The constrained contenders (n = 2 only) and their formulations.
CONSTRAINED_ROWS = {"lagcodegen index-1": "index1", "lagcodegen GGL": "ggl"}

CASADI = r"""
import json, sys, time
t0 = time.perf_counter()
import casadi as ca
t1 = time.perf_counter()
n = int(sys.argv[1])
q = ca.SX.sym("q", n); v = ca.SX.sym("v", n)
g, l, m = 9.81, 1.0, 1.0
x = y = 0; xd = yd = 0; T = 0; V = 0
for i in range(n):  # planar chain of point masses, links of length l
    x = x + l * ca.sin(q[i]); y = y - l * ca.cos(q[i])
    xd = xd + l * ca.cos(q[i]) * v[i]; yd = yd + l * ca.sin(q[i]) * v[i]
    T = T + 0.5 * m * (xd ** 2 + yd ** 2); V = V + m * g * y
L = T - V
M = ca.jacobian(ca.gradient(L, v), v)
F = ca.gradient(L, q) - ca.jacobian(ca.gradient(L, v), q) @ v
acc = ca.solve(M, F)
f = ca.integrator("f", "cvodes", {"x": ca.vertcat(q, v), "ode": ca.vertcat(v, acc)}, 0.0, [10.0],
                  {"reltol": 1e-8, "abstol": 1e-10})
t2 = time.perf_counter()
out = f(x0=[1.0] * n + [0.0] * n)
t3 = time.perf_counter()
print(json.dumps(dict(imports=t1 - t0, build=t2 - t1, first=t3 - t1, y=float(out["xf"][0]), cached=False)))
"""


def run(script: str, n: int, env: dict, *extra: str) -> dict:
    proc = subprocess.run([sys.executable, "-c", script, str(n), *extra], capture_output=True, text=True, env=env,
                          timeout=600)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-2000:])
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="2 rounds")
    ap.add_argument("--rounds", type=int, default=None)
    ap.add_argument("--out", type=Path, default=Path("out") / TAG)
    args = ap.parse_args(argv)
    rounds = args.rounds or (2 if args.quick else 5)
    args.out.mkdir(parents=True, exist_ok=True)
    load_before = H.load_average()
    try:
        import casadi  # noqa: F401
        have_casadi = True
    except ImportError:
        have_casadi = False
    warm = Path(tempfile.mkdtemp(prefix="lcg-first-answer-"))
    base_env = dict(os.environ)
    run(LAGCODEGEN, 1, {**base_env, "LAGCODEGEN_CACHE": str(warm)})  # the runtime, once
    contenders = {"lagcodegen": lambda n: run(LAGCODEGEN, n, {**base_env, "LAGCODEGEN_CACHE": str(warm)}),
                  "lagcodegen, empty cache": lambda n: run(
                      LAGCODEGEN, n, {**base_env, "LAGCODEGEN_CACHE": tempfile.mkdtemp(prefix="lcg-empty-")})}
    for label, form in CONSTRAINED_ROWS.items():
        contenders[label] = (lambda form: lambda n: run(CONSTRAINED, n, {**base_env, "LAGCODEGEN_CACHE": str(warm)},
                                                        form))(form)
    if have_casadi:
        contenders["casadi"] = lambda n: run(CASADI, n, base_env)
    samples: dict = {}
    for r in range(rounds):
        for n in (1, 2):
            for name, fn in contenders.items():
                if name in CONSTRAINED_ROWS and n != 2:
                    continue  # the Cartesian pendulum has 2 coordinates
                H.progress(TAG, f"round {r + 1}/{rounds}: {name}, n = {n}")
                samples.setdefault((name, n), []).append(fn(n))
    rows = []
    for (name, n), runs in samples.items():
        med = {k: statistics.median(s[k] for s in runs) for k in ("imports", "build", "first")}
        rows.append(dict(contender=name, n=n, first_s=med["first"], build_s=med["build"], imports_s=med["imports"],
                         y_end=runs[0]["y"]))
    for row in rows:
        ref = next((r for r in rows if r["contender"] == "casadi" and r["n"] == row["n"]), None)
        if row["contender"] in CONSTRAINED_ROWS:
            ref = None  # another model (a pendulum in Cartesian coordinates): no CasADi counterpart
        row["vs_casadi"] = row["first_s"] / ref["first_s"] if ref else None
    cols = [("contender", "contender", "{}"), ("n", "n", "{}"), ("first_s", "first answer [s]", "{:.3f}"),
            ("build_s", "build [s]", "{:.3f}"), ("imports_s", "imports [s]", "{:.3f}"),
            ("vs_casadi", "/ casadi", "{:.2f}"), ("y_end", "q1(10)", "{:.10f}")]
    table = H.format_table(cols, rows)
    text = "\n".join(H.machine_lines("Time to a first answer (new process, model never built)",
                                     (load_before, H.load_average()))
                     + ["", f"medians of {rounds} rounds; first answer = compile/build + first simulate, "
                        "imports excluded", "", table])
    print(text)
    H.write_report(args.out, TAG, text, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
