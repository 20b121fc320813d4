"""A cart-pole driven by a force table: the same piecewise-constant force F(t) given to
lagcodegen's simulate() (``inputs={"F": lagcodegen.Table(..., kind="zoh")}``, interpolated in C
by the CVODE driver, which restarts at each jump) and to the cart-pole's FMU (FMI 2.0 and 3.0,
written by ``lagcodegen.export_fmu``) simulated by FMPy, Model Exchange (FMPy's CVODE) and
Co-Simulation (1 ms communication step).

Co-Simulation at rtol 1e-8 agrees with simulate() to about 5e-9 of each state's range (the FMU's
Dormand-Prince between the jumps, which fall on communication points). Model Exchange at rtol
1e-8 differs by about 9e-6: FMPy's own CVODE error on this unstable system (the pole falls over:
without any input the same FMU in FMPy differs by 1e-4 from simulate() at that tolerance);
at rtol 1e-10 the difference is about 2e-7.

Needs FMPy (``pip install fmpy``, in the ``test`` extra). Writes out/cartpole_fmi{2,3}.fmu and
out/cartpole_fmu.png.
"""

from pathlib import Path

import numpy as np
import sympy as sp
from fmpy import simulate_fmu
from fmpy.validation import validate_fmu

import lagcodegen as lcg

T_END = 5.0
NAMES = ["x", "theta", "x_dot", "theta_dot"]


def cartpole() -> lcg.Model:
    """A cart of mass M on a rail (position x) carrying a pole of mass m at distance l, at the
    angle theta from the upright; a horizontal force F (an input) pushes the cart."""
    m = lcg.Model("cartpole")
    x, th = m.coordinates("x theta")
    M, mp, l, g = m.parameters(M=1.0, m=0.3, l=0.5, g=9.81)
    F = m.input("F")
    m.particle("cart", M, (x, 0))
    m.particle("pole", mp, (x + l * sp.sin(th), l * sp.cos(th)))
    m.gravity(g)
    m.generalized_force(x, F)
    m.output("force", F)
    for name, unit in (("x", "m"), ("theta", "rad"), ("M", "kg"), ("m", "kg"), ("l", "m"), ("g", "m/s2"),
                       ("F", "N")):
        m.unit(name, unit)  # carried into the FMU's modelDescription
    return m


#: The force table: a push, a pull and a rest, held between its times.
TIMES = np.array([0.0, 0.5, 1.0, 1.5, 2.5, 3.0, 4.0])
FORCE = np.array([0.0, 2.0, -3.0, 1.0, 0.0, -1.5, 0.5])


def fmpy_signal() -> np.ndarray:
    """The same zero-order hold as FMPy's input: a repeated time marks each jump."""
    rows = [(TIMES[0], FORCE[0])]
    for k in range(1, TIMES.size):
        rows += [(TIMES[k], FORCE[k - 1]), (TIMES[k], FORCE[k])]
    rows.append((T_END, FORCE[-1]))
    return np.array(rows, dtype=[("time", float), ("F", float)])


def run(out: Path = Path("out"), plot: bool = True) -> dict:
    """Export, validate, simulate both ways; return the largest relative differences."""
    out.mkdir(exist_ok=True)
    model = cartpole()
    t = np.linspace(0.0, T_END, 501)
    q0 = {"x": 0.0, "theta": 0.2}
    sim = lcg.compile_model(model, outputs=["force"])
    ref = sim.simulate(t, q0=q0, inputs={"F": lcg.Table(TIMES, FORCE, kind="zoh")}, rtol=1e-10, atol=1e-12)
    differences, runs = {}, {}
    for version in (2, 3):
        path = lcg.export_fmu(model, out / f"cartpole_fmi{version}.fmu", fmi_version=version, outputs=["force"],
                              initial={"theta": 0.2})
        problems = validate_fmu(str(path))
        assert not problems, problems
        for kind, rtol, options in (("ModelExchange", 1e-8, dict(solver="CVode")),
                                    ("ModelExchange", 1e-10, dict(solver="CVode")), ("CoSimulation", 1e-8, {})):
            res = simulate_fmu(str(path), fmi_type=kind, stop_time=T_END, output_interval=1e-3,
                               relative_tolerance=rtol, input=fmpy_signal(), output=NAMES + ["force"], **options)
            if rtol == 1e-8:
                runs[version, kind] = res
            differences[version, kind, rtol] = max(
                np.max(np.abs(np.interp(t, res["time"], res[n]) - ref[n])) / np.ptp(ref[n]) for n in NAMES)
    for (version, kind, rtol), d in differences.items():
        print(f"FMI {version}.0 {kind:13s} rtol {rtol:.0e}: largest difference from simulate(), relative to the "
              f"range: {d:.1e}")
    print(f"simulate(): {ref.stats['restarts']} restarts, {ref.stats['err_test_fails']} rejected steps "
          f"of {ref.stats['steps']}")
    if plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
        ax1.step(TIMES.tolist() + [T_END], FORCE.tolist() + [FORCE[-1]], "k", where="post", label="F table")
        ax1.set_ylabel("force F (N)")
        ax2.plot(t, ref["theta"], "k", lw=2.5, alpha=0.35, label="simulate(inputs=Table)")
        for (version, kind), style in zip(runs, ("C0--", "C1:", "C2--", "C3:")):
            ax2.plot(runs[version, kind]["time"], runs[version, kind]["theta"], style, lw=1,
                     label=f"FMPy FMI {version}.0 {kind}")
        ax2.set_ylabel("pole angle theta (rad)")
        ax2.set_xlabel("t (s)")
        ax2.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out / "cartpole_fmu.png", dpi=100)
        print(f"wrote {out / 'cartpole_fmu.png'}")
    return differences


if __name__ == "__main__":
    run()
