"""Overhead of lagcodegen's native driver against a hand-written CVODE program.

benchmarks/hand_cvode.c calls CVODE directly on the same generated ``<prefix>_rhs`` /
``<prefix>_jac`` (it includes the generated header and lagcodegen's sundials_api.h and links
the SUNDIALS libraries bundled in the scikit-sundae wheel with -l:<file> and an rpath). For
the double pendulum and the planar 10-link pendulum, each angle 0.5 rad at rest, t in [0, 10]
with 1001 output times, rtol 1e-8, atol 1e-10, it is timed against lagcodegen's native driver
in the same configurations (Adams with the generated Jacobian -- lagcodegen's default --,
Adams with difference quotients, BDF with the generated Jacobian):

* hand [ms]        one complete solve in the C program (context, vectors and solver created
                   and freed each time), median of --repeats, timed inside the program;
* driver [ms]      ``lcg_cvode_solve`` (the model-independent driver, on the model's function
                   table) called through cffi with preallocated arrays (the driver alone);
* simulate [ms]    ``CompiledModel.simulate`` (the Python API: checks, one RHS call at the
                   initial state, array allocation, the Result);
* ratios           driver / hand and simulate / hand (target: within 1.2x), and the largest
                   difference between the final states (the same steps are expected: 0).

Usage::

    python benchmarks/native_overhead.py [--quick] [--out DIR] [--repeats N]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

from lagcodegen import Scene, build_code, derive, generate_c, systems  # noqa: E402
from lagcodegen.build import driver_sources, find_sundials  # noqa: E402

TAG = "native_overhead"
HERE = Path(__file__).resolve().parent
T_END, NT, Q0 = 10.0, 1001, 0.5
RTOL, ATOL = 1e-8, 1e-10
TARGET = 1.2
CONFIGS = (("adams", True), ("adams", False), ("bdf", True))
STRICT = ["-O2", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]


def progress(message: str) -> None:
    H.progress(TAG, message)


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="5 repeats (< 1 min)")
    ap.add_argument("--out", metavar="DIR", type=Path, help="write native_overhead.txt and .csv")
    ap.add_argument("--repeats", type=int, help="runs per median (default 21; quick 5)")
    return ap.parse_args(argv)


def alias_header(code) -> str:
    pre, PRE = code.prefix, code.prefix.upper()
    params = ", ".join(repr(float(v)) for v in code.param_defaults) or "0.0"
    lines = [f'#include "{pre}.h"', f"#define MODEL_NY {PRE}_NY", f"#define MODEL_NQ {PRE}_NQ",
             f"#define MODEL_HAS_JAC {1 if code.jacobian else 0}", f"#define model_rhs {pre}_rhs"]
    if code.jacobian:
        lines.append(f"#define model_jac {pre}_jac")
    lines.append(f"static const double model_p[] = {{{params}}};")
    return "\n".join(lines) + "\n"


def build_hand(code, folder: Path) -> Path:
    """Compile hand_cvode.c against the generated model in ``folder`` (strict warnings)."""
    sundials = find_sundials()
    folder.mkdir(parents=True, exist_ok=True)
    code.write(folder)
    for name in ("sundials_api.h", "lcg_config.h"):
        (folder / name).write_text(driver_sources(code, sundials)[name])
    (folder / "model_alias.h").write_text(alias_header(code))
    (folder / "hand_cvode.c").write_text((HERE / "hand_cvode.c").read_text())
    cmd = [H.c_compiler(), *STRICT, "hand_cvode.c", code.source_name, "-o", "hand_cvode",
           *sundials.link_args(("cvode", "core")), "-lm"]
    proc = subprocess.run(cmd, cwd=folder, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"compiling hand_cvode.c failed:\n{' '.join(cmd)}\n{proc.stderr}")
    return folder / "hand_cvode"


def run_hand(exe: Path, method: str, jac: bool, repeats: int) -> tuple[float, np.ndarray, int]:
    args = [str(exe), "1" if method == "adams" else "2", "1" if jac else "0", repr(RTOL), repr(ATOL), repr(T_END),
            str(NT), repr(Q0), str(repeats)]
    proc = subprocess.run(args, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"hand_cvode failed: {proc.stderr}")
    parts = proc.stdout.split()
    return float(parts[1]), np.array([float(x) for x in parts[7:]]), int(parts[3])


def driver_call(cm, method: str, jac: bool):
    """A function running the native CVODE driver (``lcg_cvode_solve`` on the model's function
    table) once through cffi with preallocated arrays."""
    ffi = cm.ffi
    t = np.linspace(0.0, T_END, NT)
    y0 = np.array([Q0] * cm.n + [0.0] * cm.n)
    p = cm.parameter_vector()
    yout = np.empty((NT, cm.ny))
    out = np.empty((NT, 1))
    opt = ffi.new(f"{cm.options_type} *")
    st = ffi.new(cm.stats_type)
    opt.method = 1 if method == "adams" else 2
    opt.jacobian = int(jac)
    opt.rtol, opt.atol, opt.atol_vec = RTOL, ATOL, ffi.NULL
    opt.max_steps = 1_000_000
    args = (ffi.from_buffer("double[]", p), ffi.from_buffer("double[]", y0), NT, ffi.from_buffer("double[]", t),
            ffi.from_buffer("double[]", yout), ffi.from_buffer("double[]", out), opt, st)
    fn = cm.native_solve

    def call():
        if fn(*args) != 0:
            raise RuntimeError("driver failed")
        return yout[-1].copy(), st.nsteps
    return call


def measure(label: str, model, repeats: int, scratch: Path) -> list[dict]:
    progress(f"{label}: generate, build, compile hand_cvode.c")
    code = generate_c(Scene(derive(model), jacobian=True, prefix=f"ovh_{model.name}"))
    cm = build_code(code)
    exe = build_hand(code, scratch / model.name)
    rows = []
    t = np.linspace(0.0, T_END, NT)
    for method, jac in CONFIGS:
        progress(f"{label}: {method}, {'generated' if jac else 'DQ'} Jacobian")
        call = driver_call(cm, method, jac)
        call()
        hand_s, y_hand, hand_steps = run_hand(exe, method, jac, repeats)
        def simulate():
            return cm.simulate(t, q0=[Q0] * cm.n, rtol=RTOL, atol=ATOL, method=method, jacobian=jac)
        simulate()  # warm-up
        drv_times, sim_times, res = [], [], None
        for _ in range(repeats):  # interleaved, so that machine noise hits both alike
            start = time.perf_counter()
            y_drv, drv_steps = call()
            drv_times.append(time.perf_counter() - start)
            start = time.perf_counter()
            res = simulate()
            sim_times.append(time.perf_counter() - start)
        hand_s2, _, _ = run_hand(exe, method, jac, repeats)  # bracket the Python runs in time
        hand = min(hand_s, hand_s2)
        drv, sim = statistics.median(drv_times), statistics.median(sim_times)
        rows.append(dict(system=label, n=cm.n, method=method, jacobian="generated" if jac else "DQ",
                         steps=int(drv_steps), hand_steps=hand_steps, hand_ms=1e3 * hand, driver_ms=1e3 * drv,
                         simulate_ms=1e3 * sim, driver_ratio=drv / hand, simulate_ratio=sim / hand,
                         max_dy=float(np.max(np.abs(y_drv - y_hand))),
                         max_dy_sim=float(np.max(np.abs(res.y[-1] - y_hand)))))
    return rows


COLUMNS = [
    ("system", "system", "{}"), ("method", "method", "{}"), ("jacobian", "Jacobian", "{}"), ("steps", "steps", "{}"),
    ("hand_steps", "hand steps", "{}"), ("hand_ms", "hand [ms]", "{:.3f}"), ("driver_ms", "driver [ms]", "{:.3f}"),
    ("simulate_ms", "simulate [ms]", "{:.3f}"), ("driver_ratio", "driver/hand", "{:.3f}"),
    ("simulate_ratio", "simulate/hand", "{:.3f}"), ("max_dy", "max |dy(T)|", "{:.1e}"),
]


def main(argv=None) -> int:
    args = parse_args(argv)
    repeats = args.repeats or (5 if args.quick else 21)
    start, load_start = time.perf_counter(), H.load_average()
    rows = []
    with tempfile.TemporaryDirectory(prefix="lcg-overhead-") as tmp:
        for label, model in (("double pendulum", systems.double_pendulum("ovh_double")),
                             ("10-link pendulum", systems.n_link_pendulum(10, name="ovh_link10"))):
            rows += measure(label, model, repeats, Path(tmp))
    lines = H.machine_lines("lagcodegen native driver vs hand-written CVODE", (load_start, H.load_average()))
    lines += [f"run:      t in [0, {T_END:g}], {NT} output times, every angle {Q0} rad at rest, rtol {RTOL:g}, "
              f"atol {ATOL:g}; medians of {repeats} solves (hand: the faster of two batches of {repeats})",
              f"          hand_cvode.c compiled with cc {' '.join(STRICT)}; lagcodegen with its build flags "
              "(-O2 -fPIC -std=c99)", "",
              H.format_table(COLUMNS, rows), ""]
    worst = max(rows, key=lambda r: r["simulate_ratio"])
    worst_drv = max(rows, key=lambda r: r["driver_ratio"])
    lines.append(f"target {TARGET:g}x: driver/hand worst {worst_drv['driver_ratio']:.3f} "
                 f"({worst_drv['system']}, {worst_drv['method']}, {worst_drv['jacobian']}); simulate/hand worst "
                 f"{worst['simulate_ratio']:.3f} ({worst['system']}, {worst['method']}, {worst['jacobian']}): "
                 + ("met" if max(worst["simulate_ratio"], worst_drv["driver_ratio"]) <= TARGET else "MISSED"))
    text = "\n".join(lines) + "\n"
    print(text, end="")
    if args.out is not None:
        H.write_report(args.out, "native_overhead", text, rows)
        progress(f"wrote {args.out}/native_overhead.txt and .csv")
    progress(f"done in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
