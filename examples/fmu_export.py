"""The double pendulum as an FMU (FMI 2.0 and 3.0, Model Exchange and Co-Simulation in one
archive), simulated by FMPy and compared with lagcodegen's own simulate().

Needs FMPy (``pip install fmpy``, in the ``test`` extra). The same FMU comes from the command line:
``lagcodegen generate examples/double_pendulum.toml --fmu out/double_pendulum.fmu [--fmi 3]``.
"""

import time
from pathlib import Path

import numpy as np
from fmpy import simulate_fmu
from fmpy.validation import validate_fmu

import lagcodegen as lcg

here = Path(__file__).resolve().parent
out = Path("out")
out.mkdir(exist_ok=True)
mf = lcg.modelfile.load_model(here / "double_pendulum.toml")
T_END = 5.0

paths = {}
for version in (2, 3):
    start = time.perf_counter()
    paths[version] = lcg.export_fmu(mf, out / f"double_pendulum_fmi{version}.fmu", fmi_version=version)
    problems = validate_fmu(str(paths[version]))
    print(f"FMI {version}.0: wrote {paths[version]} in {time.perf_counter() - start:.2f} s; FMPy's validation: "
          f"{'no problem' if not problems else problems}")

# The reference: lagcodegen's CVODE at a tight tolerance.
t = np.linspace(0.0, T_END, 501)
q0, v0 = mf.initial_state()
ref = lcg.compile_file(mf).simulate(t, q0=q0, v0=v0, rtol=1e-12, atol=1e-14)

runs = {}
names = ["theta1", "theta2", "energy"]
for kind, options in (("ModelExchange", dict(solver="CVode")), ("CoSimulation", {})):
    start = time.perf_counter()
    runs[kind] = simulate_fmu(str(paths[3]), fmi_type=kind, stop_time=T_END, output_interval=1e-3,
                              relative_tolerance=1e-8, output=names, **options)
    err = max(np.max(np.abs(np.interp(t, runs[kind]["time"], runs[kind][n]) - ref[n])) / np.max(np.abs(ref[n]))
              for n in names)
    print(f"FMPy {kind:13s} {time.perf_counter() - start:5.2f} s  largest difference from simulate(), relative "
          f"to the range: {err:.1e}")

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
ax1.plot(t, ref["theta1"], "k", lw=2.5, alpha=0.35, label="simulate() theta1")
ax1.plot(t, ref["theta2"], "k", lw=2.5, alpha=0.2, label="simulate() theta2")
for kind, style in (("ModelExchange", "--"), ("CoSimulation", ":")):
    r = runs[kind]
    ax1.plot(r["time"], r["theta1"], "C0" + style, lw=1, label=f"FMPy {kind} theta1")
    ax1.plot(r["time"], r["theta2"], "C1" + style, lw=1, label=f"FMPy {kind} theta2")
    ax2.semilogy(t, np.abs(np.interp(t, r["time"], r["theta2"]) - ref["theta2"]) + 1e-16, style, lw=1,
                 label=f"{kind}: |theta2 - simulate()|")
ax1.set_ylabel("angle (rad)")
ax1.legend(fontsize=7, ncol=2)
ax2.set_xlabel("t")
ax2.set_ylabel("difference (rad)")
ax2.legend(fontsize=7)
fig.suptitle("double pendulum: FMU (FMI 3.0) in FMPy against simulate()")
fig.tight_layout()
fig.savefig(out / "fmu_export.png", dpi=100)
print("wrote out/fmu_export.png")
