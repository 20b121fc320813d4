"""Work-precision diagrams: wall time vs error of every integrator lagcodegen can drive.

Scenes (y: the compared quantities; errors are relative per component, see below):

* ``pendulum``       simple pendulum at large amplitude, theta0 = 3.0 rad (172 deg), t in [0, 20];
* ``double``         chaotic double pendulum, theta1 = theta2 = 2.0 rad at rest, t in [0, 5];
* ``spherical``      spherical pendulum, full coordinates (theta, phi), theta0 = 0.8, theta0' = 0.3,
                     phi0' = 2.0, t in [0, 20], compared on (theta, phi, theta');
* ``spherical_routh`` the same motion, Routhian-reduced over phi (theta'' from L_R = -R, phi as a
                     quadrature state), compared on the same (theta, phi, theta');
* ``hoop``           bead on a hoop spinning at w = 5 (explicitly time-dependent), theta0 = 1.0,
                     t in [0, 20];
* ``constrained``    Cartesian pendulum x^2 + y^2 = 1 released from 1 rad, t in [0, 10], compared
                     on (x, y), under each formulation of compile_constrained: index-1 (Adams),
                     index-1 + Baumgarte (10, 10), index-1 + projection (BDF), GGL on native IDA
                     and on scikit-sundae's IDA, minimal coordinates;
* ``chain``          stiff chain of 20 unit masses between walls, springs alternating k = 1 and
                     1e6 k (critically damped dimers), the first dimer displaced by 0.1,
                     t in [0, 10] (Jacobian band: native band solver with the sparse Jacobian);
* ``nlink``          planar 10-link pendulum, every angle 0.5 rad, t in [0, 5].

Contenders in one run: native CVODE (Adams and BDF, each with the generated and the
difference-quotient Jacobian; band solver on the chain), native IDA (constraint scene), the
scikit-sundae callback backend, scipy's solve_ivp (RK45, DOP853, LSODA, Radau; LSODA and
Radau with the generated Jacobian ``cm.jac``) on the compiled right-hand side ``cm.rhs``, and
scipy (DOP853; Radau on the chain) on a sympy-lambdify right-hand side (M and F lambdified
with cse from ``eom.M``, ``eom.F``, ``numpy.linalg.solve`` at every call). rtol runs from
1e-3 to 1e-12 (atol = rtol/100); --quick: 1e-3, 1e-6, 1e-9.

Reference: scipy DOP853 (Radau with ``cm.jac`` on the chain) at rtol 1e-13, atol 1e-15 on the
compiled right-hand side (for the constraint scene: of the simple pendulum in the angle,
mapped to (x, y); for both spherical scenes: of the full model), checked by convergence
against the same at rtol 1e-12 (the difference is printed as the reference uncertainty;
errors below about 10x that are not resolved). --quick: 1e-11 against 1e-10.

Errors: on a grid of 201 output times; the error of component i is |y_i - ref_i| / s_i with
s_i = max over t of |ref_i| (at least 1e-3 times the largest s_j); reported are the max
over components at the final time (err(T)) and over the whole grid (max err).

Times: wall time of one call that integrates and returns the grid (simulate() for the
lagcodegen backends: includes the Python wrapper, ~20 us), median of --repeats runs for runs
under 0.5 s. Every contender has a time budget per scene (--budget, default 10 s; 2 s with
--quick): a contender whose next, tighter run would exceed it is skipped from there on, and
a scipy run is stopped when it does (shown as "budget" in the table).

Summary: per scene, the configuration with the least interpolated time (log-log along the
contender's points) at max err 1e-4, 1e-6, 1e-8; "<=" marks an upper bound (every run of
that contender was more accurate than the target).

Outputs: the tables on stdout (progress on stderr); with --out DIR: work_precision.txt,
work_precision.csv and one PNG per scene, wp_<scene>.png.

This is a measuring instrument: it asserts nothing about the times it reports.

Usage::

    python benchmarks/work_precision.py [--quick] [--out DIR] [--scenes a,b] [--budget S] [--repeats N]
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

import lagcodegen as lcg  # noqa: E402
from lagcodegen import Scene, build_code, derive, generate_c, systems  # noqa: E402
from lagcodegen.errors import LagcodegenError  # noqa: E402

TAG = "work_precision"
SCENES = ("pendulum", "double", "spherical", "spherical_routh", "hoop", "constrained", "chain", "nlink")
TARGETS = (1e-4, 1e-6, 1e-8)
N_GRID = 201


# --------------------------------------------------------------------------- settings
@dataclass
class Settings:
    rtols: list[float]
    repeats: int = 3
    budget: float = 10.0           # seconds per contender per scene
    ref_rtol: float = 1e-13
    check_rtol: float = 1e-12
    scenes: tuple[str, ...] = SCENES
    contenders: str | None = None  # regex: only contenders whose label matches
    quick: bool = False


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="rtol 1e-3, 1e-6, 1e-9; 1 repeat; 2 s budgets (< 2 min)")
    ap.add_argument("--out", metavar="DIR", type=Path, help="write work_precision.txt/.csv and wp_<scene>.png")
    ap.add_argument("--scenes", help=f"comma-separated subset of {', '.join(SCENES)}")
    ap.add_argument("--contenders", metavar="REGEX", help="only contenders whose label matches REGEX")
    ap.add_argument("--budget", type=float, help="seconds per contender per scene (default 10; quick 2)")
    ap.add_argument("--repeats", type=int, help="runs per median for runs under 0.5 s (default 3; quick 1)")
    return ap.parse_args(argv)


def settings_from(args: argparse.Namespace) -> Settings:
    if args.quick:
        s = Settings(rtols=[1e-3, 1e-6, 1e-9], repeats=1, budget=2.0, ref_rtol=1e-11, check_rtol=1e-10, quick=True)
    else:
        s = Settings(rtols=[10.0 ** -k for k in range(3, 13)])
    if args.scenes:
        names = tuple(x.strip() for x in args.scenes.split(",") if x.strip())
        unknown = [x for x in names if x not in SCENES]
        if unknown:
            raise SystemExit(f"work_precision: unknown scene(s) {', '.join(unknown)} (known: {', '.join(SCENES)})")
        s.scenes = names
    if args.budget is not None:
        s.budget = args.budget
    if args.repeats is not None:
        s.repeats = max(1, args.repeats)
    s.contenders = args.contenders
    return s


def progress(message: str) -> None:
    H.progress(TAG, message)


# --------------------------------------------------------------------------- scenes
@dataclass
class Contender:
    """One configuration: ``run(rtol, atol, deadline_s)`` returns (compared values on the grid,
    stats dict with at least 'evals')."""

    label: str
    family: str  # native, ida, sksundae, scipy, lambdify
    run: Callable


@dataclass
class WPScene:
    key: str
    title: str
    t: np.ndarray
    ref: np.ndarray
    ref_unc: float
    scales: np.ndarray
    contenders: list[Contender]
    compared: str
    notes: list[str] = field(default_factory=list)
    setup: dict = field(default_factory=dict)  # e.g. lambdify setup seconds


def lambdify_rhs(eom, values: dict):
    """scipy-style f(t, y) from sympy.lambdify of M and F (cse), solved by numpy.linalg.solve.
    Quadrature rates (Routhian reduction) are lambdified too. Returns (f, setup seconds)."""
    import sympy as sp
    from lagcodegen.derivation import to_sp
    start = time.perf_counter()
    model = eom.model
    n = model.n
    zs = [sp.Symbol(name) for name, _ in eom.quadratures]
    args = list(model.coords) + list(model.speeds) + zs
    sub = {s: sp.Float(values[s.name]) for s in model.params}
    M = eom.M.xreplace(sub)
    F = eom.F.xreplace(sub)
    rates = [to_sp(r).xreplace(sub) for _, r in eom.quadratures]
    fn = sp.lambdify((model.t, args), [M, F, sp.Matrix(rates) if rates else sp.Matrix([0])], modules="numpy",
                     cse=True)

    def rhs(t, y):
        Mv, Fv, Rv = fn(t, y)
        a = np.linalg.solve(np.asarray(Mv, dtype=float), np.asarray(Fv, dtype=float).ravel())
        out = np.concatenate([y[n:2 * n], a])
        return np.concatenate([out, np.asarray(Rv, dtype=float).ravel()]) if rates else out

    rhs(0.0, np.full(2 * n + len(zs), 0.3))  # first call compiles nothing, but touches every path
    return rhs, time.perf_counter() - start


def native_contenders(cm, t, y0, params, select, methods=("adams", "bdf"), band=False, sks_method="adams"):
    """Native CVODE (Adams/BDF x analytic/DQ Jacobian, band variants) and sksundae."""
    out = []

    def make(method, jac, backend="native", linear_solver="dense"):
        def run(rtol, atol, _deadline):
            res = cm.simulate(t, y0=y0, params=params, method=method, rtol=rtol, atol=atol, jacobian=jac,
                              backend=backend, linear_solver=linear_solver, max_steps=20_000_000)
            return select(res), dict(evals=res.stats.get("rhs_evals"), steps=res.stats.get("steps"))
        return run

    for method in methods:
        for jac in (True, False):
            label = f"CVODE {method.upper() if method == 'bdf' else 'Adams'} {'jac' if jac else 'DQ'}"
            out.append(Contender(f"{label} (native)", "native", make(method, jac)))
        if band:
            for jac in (True, False):
                label = f"CVODE {method.upper() if method == 'bdf' else 'Adams'} band {'sparse jac' if jac else 'DQ'}"
                out.append(Contender(f"{label} (native)", "native", make(method, jac, linear_solver="band")))
    label = "BDF" if sks_method == "bdf" else "Adams"
    out.append(Contender(f"CVODE {label} jac (scikit-sundae)", "sksundae", make(sks_method, True, "sksundae")))
    return out


def scipy_contenders(fun, jac, t, y0, select, methods, family="scipy", suffix="cm.rhs"):
    out = []
    for method in methods:
        def run(rtol, atol, deadline, method=method):
            y, _wall, nfev = H.scipy_solution(fun, t, y0, method, rtol, atol, jac=jac, budget=deadline)
            return select(y), dict(evals=nfev, steps=None)
        label = f"scipy {method}{' +jac' if jac is not None and method in ('Radau', 'LSODA') else ''} ({suffix})"
        out.append(Contender(label, family, run))
    return out


def compiled(eom, prefix, **scene):
    return build_code(generate_c(Scene(eom, prefix=prefix, **scene)))


def ode_scene(key, title, model_or_eom, q0, v0, T, settings, stiff=False, band=False, compared="all states",
              prefix=None, params=None):
    """A scene of one unconstrained model: every contender on its compiled module."""
    eom = model_or_eom if isinstance(model_or_eom, lcg.EquationsOfMotion) else derive(model_or_eom)
    cm = compiled(eom, prefix or f"wp_{key}", sparse_jacobian=band)
    t = np.linspace(0.0, T, N_GRID)
    y0 = np.concatenate([q0, v0]).astype(float)
    p = cm.parameter_vector(params)
    pvals = dict(zip(cm.param_names, p))

    def fun(tt, y):
        return cm.rhs(tt, y, p)

    def jac(tt, y):
        return cm.jac(tt, y, p)

    ref_method = "Radau" if stiff else "DOP853"
    ref, ref_unc = reference(fun, jac if stiff else None, t, y0, ref_method, settings)

    def ident(x):
        return x if isinstance(x, np.ndarray) else x.y

    conts = native_contenders(cm, t, y0, pvals, ident, band=band, sks_method="bdf" if stiff else "adams")
    conts += scipy_contenders(fun, jac, t, y0, ident, ("RK45", "DOP853", "LSODA", "Radau"))
    lam, setup = lambdify_rhs(eom, {**{s.name: v for s, v in eom.model.params.items()}, **pvals})
    conts += scipy_contenders(lam, None, t, y0, ident, ("Radau",) if stiff else ("DOP853",), "lambdify",
                              "lambdify")
    notes = [f"reference: scipy {ref_method}{' +jac' if stiff else ''} rtol {settings.ref_rtol:g} on cm.rhs"]
    return WPScene(key, title, t, ref, ref_unc, H.error_scales(ref), conts, compared, notes,
                   {"lambdify setup [s]": setup})


def reference(fun, jac, t, y0, method, settings):
    """Reference on the grid and its uncertainty (difference from a 10x looser run, in the
    error metric of the scene)."""
    ref, _, _ = H.scipy_solution(fun, t, y0, method, settings.ref_rtol, settings.ref_rtol * 1e-2, jac=jac)
    check, _, _ = H.scipy_solution(fun, t, y0, method, settings.check_rtol, settings.check_rtol * 1e-2, jac=jac)
    scales = H.error_scales(ref)
    return ref, H.errors(check, ref, scales)[1]


def scene_pendulum(settings):
    return ode_scene("pendulum", "simple pendulum, theta0 = 3.0 rad, t in [0, 20]", systems.pendulum("wp_pend"),
                     [3.0], [0.0], 20.0, settings)


def scene_double(settings):
    return ode_scene("double", "chaotic double pendulum, theta1 = theta2 = 2.0 rad, t in [0, 5]",
                     systems.double_pendulum("wp_double"), [2.0, 2.0], [0.0, 0.0], 5.0, settings)


def scene_hoop(settings):
    return ode_scene("hoop", "bead on a hoop spinning at w = 5, theta0 = 1.0, t in [0, 20]",
                     systems.bead_on_spinning_hoop("wp_hoop"), [1.0], [0.0], 20.0, settings)


def scene_nlink(settings):
    n = 10
    return ode_scene("nlink", f"{n}-link pendulum, every angle 0.5 rad, t in [0, 5]",
                     systems.n_link_pendulum(n, name="wp_nlink"), [0.5] * n, [0.0] * n, 5.0, settings)


def scene_chain(settings):
    n = 20
    q0, v0 = H.chain_initial(n)
    return ode_scene("chain", f"stiff chain, {n} masses, springs 1 / 1e6 alternating (critically damped dimers), "
                     "t in [0, 10]", H.spring_chain(n, 1e6, name="wp_chain"), q0, v0, 10.0, settings,
                     stiff=True, band=True)


SPH_Q0, SPH_V0, SPH_T = (0.8, 0.0), (0.3, 2.0), 20.0


def spherical_reference(settings, t):
    """(theta, phi, theta') of the full spherical pendulum from DOP853 on its compiled RHS."""
    cm = compiled(derive(systems.spherical_pendulum("wp_sph")), "wp_sph")
    p = cm.parameter_vector()

    def fun(tt, y):
        return cm.rhs(tt, y, p)

    ref, unc = reference(fun, None, t, [*SPH_Q0, *SPH_V0], "DOP853", settings)
    return ref[:, [0, 1, 2]], unc, cm


def scene_spherical(settings):
    t = np.linspace(0.0, SPH_T, N_GRID)
    ref, unc, cm = spherical_reference(settings, t)
    y0 = np.array([*SPH_Q0, *SPH_V0])
    p = cm.parameter_vector()
    pvals = dict(zip(cm.param_names, p))

    def sel(x):
        y = x if isinstance(x, np.ndarray) else x.y
        return y[:, [0, 1, 2]]

    def fun(tt, y):
        return cm.rhs(tt, y, p)

    def jac(tt, y):
        return cm.jac(tt, y, p)

    conts = native_contenders(cm, t, y0, pvals, sel)
    conts += scipy_contenders(fun, jac, t, y0, sel, ("RK45", "DOP853", "LSODA", "Radau"))
    lam, setup = lambdify_rhs(derive(systems.spherical_pendulum("wp_sph")), pvals)
    conts += scipy_contenders(lam, None, t, y0, sel, ("DOP853",), "lambdify", "lambdify")
    return WPScene("spherical", f"spherical pendulum, full (theta, phi), t in [0, {SPH_T:g}]", t, ref, unc,
                   H.error_scales(ref), conts, "theta, phi, theta'",
                   ["reference: scipy DOP853 rtol %g on the full model's cm.rhs" % settings.ref_rtol],
                   {"lambdify setup [s]": setup})


def scene_spherical_routh(settings):
    from lagcodegen.theory.routhian import reduce
    t = np.linspace(0.0, SPH_T, N_GRID)
    ref, unc, _ = spherical_reference(settings, t)
    red = reduce(systems.spherical_pendulum("wp_sph"))
    cm = lcg.compile_reduction(red, outputs=(), prefix="wp_sph_routh")
    y0, params = red.initial_state(cm, SPH_Q0, SPH_V0)
    p = cm.parameter_vector(params)
    # reduced state (theta, theta', phi) -> compared (theta, phi, theta')

    def sel(x):
        y = x if isinstance(x, np.ndarray) else x.y
        return y[:, [0, 2, 1]]

    def fun(tt, y):
        return cm.rhs(tt, y, p)

    def jac(tt, y):
        return cm.jac(tt, y, p)

    conts = native_contenders(cm, t, y0, params, sel)
    conts += scipy_contenders(fun, jac, t, y0, sel, ("RK45", "DOP853", "LSODA", "Radau"))
    full_values = {s.name: v for s, v in red.eom.model.params.items()}
    full_values.update(params)
    lam, setup = lambdify_rhs(red.eom, full_values)
    conts += scipy_contenders(lam, None, t, y0, sel, ("DOP853",), "lambdify", "lambdify")
    return WPScene("spherical_routh", f"spherical pendulum, Routhian-reduced (theta; phi by quadrature), "
                   f"t in [0, {SPH_T:g}]", t, ref, unc, H.error_scales(ref), conts, "theta, phi, theta'",
                   ["reference: the full model's (scene spherical)"], {"lambdify setup [s]": setup})


def scene_constrained(settings):
    from lagcodegen.api import compile_constrained
    theta0, T = 1.0, 10.0
    t = np.linspace(0.0, T, N_GRID)
    pend = compiled(derive(systems.pendulum("wp_cpend_ref")), "wp_cpend_ref")
    pp = pend.parameter_vector()

    def fun_ref(tt, y):
        return pend.rhs(tt, y, pp)

    ref_th, unc_th = reference(fun_ref, None, t, [theta0, 0.0], "DOP853", settings)

    def xy(theta):
        return np.column_stack([np.sin(theta), -np.cos(theta)])

    ref = xy(ref_th[:, 0])
    system = H.cartesian_pendulum()
    sims = {form: compile_constrained(system, form, prefix=f"wp_c_{form}") for form in ("index1", "ggl", "minimal")}
    q0, v0 = [math.sin(theta0), -math.cos(theta0)], [0.0, 0.0]

    def sel(res):
        return np.column_stack([res["x"], res["y"]])

    def make(form, **opts):
        def run(rtol, atol, _deadline):
            res = sims[form].simulate(t, q0=q0, v0=v0, rtol=rtol, atol=atol, max_steps=20_000_000, **opts)
            return sel(res), dict(evals=res.stats.get("rhs_evals", res.stats.get("res_evals")),
                                  steps=res.stats.get("steps"))
        return run

    conts = [
        Contender("index-1 Adams (native CVODE)", "native", make("index1")),
        Contender("index-1 + Baumgarte(10,10) Adams (native CVODE)", "native", make("index1", baumgarte=(10.0, 10.0))),
        Contender("index-1 + projection BDF (native CVODE)", "native", make("index1", projection=True)),
        Contender("index-1 Adams (scikit-sundae)", "sksundae", make("index1", backend="sksundae")),
        Contender("GGL (native IDA)", "ida", make("ggl")),
        Contender("GGL (scikit-sundae IDA)", "sksundae", make("ggl", backend="sksundae")),
        Contender("minimal Adams (native CVODE)", "native", make("minimal")),
        Contender("minimal BDF (native CVODE)", "native", make("minimal", method="bdf")),
    ]
    # scipy on the minimal coordinates' compiled RHS (and on its lambdified equations)
    vals = {"l": 1.0, "g": 9.81, "m": 1.0}
    b = sims["minimal"]._branch_for(np.array(q0), 0.0, vals, 1e-8)
    cmin = sims["minimal"].compiled_branch(b)
    pm = cmin.parameter_vector()
    y0m = np.array([q0[0], v0[0]])

    def fun_min(tt, y):
        return cmin.rhs(tt, y, pm)

    def sel_min(y):
        x = y[:, 0]
        return np.column_stack([x, -np.sqrt(np.maximum(1.0 - x * x, 0.0))])

    conts += scipy_contenders(fun_min, None, t, y0m, sel_min, ("DOP853",), suffix="minimal cm.rhs")
    lam, setup = lambdify_rhs(derive(sims["minimal"]._reduced[b]), vals)
    conts += scipy_contenders(lam, None, t, y0m, sel_min, ("DOP853",), "lambdify", "lambdify, minimal")
    # The reference uncertainty is measured in theta; it maps to (x, y) at the same order.
    return WPScene("constrained", "Cartesian pendulum x^2 + y^2 = 1, theta0 = 1 rad, t in [0, 10]", t, ref, unc_th,
                   H.error_scales(ref), conts, "x, y",
                   [f"reference: scipy DOP853 rtol {settings.ref_rtol:g} on the simple pendulum's cm.rhs "
                    "(angle), mapped to (x, y)"], {"lambdify setup [s]": setup})


BUILDERS = {"pendulum": scene_pendulum, "double": scene_double, "spherical": scene_spherical,
            "spherical_routh": scene_spherical_routh, "hoop": scene_hoop, "constrained": scene_constrained,
            "chain": scene_chain, "nlink": scene_nlink}


# --------------------------------------------------------------------------- running
def run_contender(scene: WPScene, cont: Contender, settings: Settings) -> list[dict]:
    """Every rtol of one contender, loose to tight, within the budget."""
    rows, spent, walls = [], 0.0, []
    for rtol in settings.rtols:
        row = dict(scene=scene.key, contender=cont.label, family=cont.family, rtol=rtol)
        predicted = 0.0
        if len(walls) >= 2:
            predicted = walls[-1] * min(20.0, max(1.5, walls[-1] / max(walls[-2], 1e-9)))
        elif walls:
            predicted = walls[-1] * 2.0
        if spent + predicted > settings.budget:
            row["status"] = "budget"
            rows.append(row)
            break
        deadline = max(0.5, settings.budget - spent)
        times = []
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                while True:
                    start = time.perf_counter()
                    y, stats = cont.run(rtol, rtol * 1e-2, deadline)
                    times.append(time.perf_counter() - start)
                    if len(times) >= settings.repeats or times[-1] > 0.5 or sum(times) > 0.3 * settings.budget:
                        break
        except TimeoutError:
            spent += deadline
            row["status"] = "budget"
            rows.append(row)
            break
        except (LagcodegenError, RuntimeError, np.linalg.LinAlgError, ValueError) as exc:
            row["status"] = "failed: " + " ".join(str(exc).split())[:60]
            rows.append(row)
            spent += sum(times)
            continue
        wall = float(np.median(times))
        spent += sum(times)
        walls.append(wall)
        err_final, err_max = H.errors(y, scene.ref, scene.scales)
        row.update(wall_ms=1e3 * wall, err_final=err_final, err_max=err_max, evals=stats.get("evals"),
                   steps=stats.get("steps"), status="ok" if math.isfinite(err_max) else "non-finite")
        rows.append(row)
    return rows


def run_scene(key: str, settings: Settings) -> tuple[WPScene, list[dict]]:
    progress(f"{key}: derive, compile, reference")
    start = time.perf_counter()
    scene = BUILDERS[key](settings)
    progress(f"{key}: ready in {time.perf_counter() - start:.1f} s (reference uncertainty {scene.ref_unc:.1e})")
    rows = []
    for cont in scene.contenders:
        if settings.contenders and not re.search(settings.contenders, cont.label):
            continue
        start = time.perf_counter()
        rows += run_contender(scene, cont, settings)
        progress(f"{key}: {cont.label}: {time.perf_counter() - start:.1f} s")
    return scene, rows


# --------------------------------------------------------------------------- summary and output
def curves(rows) -> dict:
    out: dict[str, list] = {}
    for r in rows:
        if r.get("status") == "ok":
            out.setdefault(r["contender"], []).append((r["err_max"], r["wall_ms"] / 1e3))
    return out


def matched_rows(scene: WPScene, rows) -> list[dict]:
    """Per contender: time at the target errors (interpolated)."""
    out = []
    for label, pts in curves(rows).items():
        row = dict(scene=scene.key, contender=label)
        for target in TARGETS:
            sec, how = H.time_at(pts, target)
            row[f"t_{target:.0e}"] = None if sec is None else 1e3 * sec
            row[f"how_{target:.0e}"] = how
        out.append(row)
    return out


def winners(scene: WPScene, rows) -> list[str]:
    lines = []
    matched = matched_rows(scene, rows)
    family = {r["contender"]: r["family"] for r in rows}
    for target in TARGETS:
        key = f"t_{target:.0e}"
        ranked = sorted((r for r in matched if r[key] is not None), key=lambda r: r[key])
        caveat = " (below 10x the reference uncertainty: not resolved)" if target < 10 * scene.ref_unc else ""
        if not ranked:
            lines.append(f"  {target:.0e}: no contender reached it{caveat}")
            continue
        best = ranked[0]
        mark = "<=" if best[f"how_{target:.0e}"] == "bound" else ""
        text = f"  {target:.0e}: {best['contender']} {mark}{best[key]:.3g} ms"
        if len(ranked) > 1:
            second = ranked[1]
            text += f"; next {second['contender']} {second[key]:.3g} ms ({second[key] / best[key]:.1f}x)"
        lines.append(text + caveat)
        # the best of every other family, relative to the winner
        others = []
        for fam in ("native", "ida", "sksundae", "scipy", "lambdify"):
            cand = [r for r in ranked if family.get(r["contender"]) == fam]
            if cand and cand[0] is not best and family.get(best["contender"]) != fam:
                others.append(f"{FAMILY_NAMES[fam]} {cand[0][key]:.3g} ms ({cand[0][key] / best[key]:.1f}x)")
        if others:
            lines.append("         best of the others: " + "; ".join(others))
    return lines


FAMILY_NAMES = {"native": "native CVODE", "ida": "native IDA", "sksundae": "scikit-sundae",
                "scipy": "scipy on cm.rhs", "lambdify": "scipy on lambdify"}


RUN_COLUMNS = [
    ("contender", "contender", "{}"),
    ("rtol", "rtol", "{:.0e}"),
    ("wall_ms", "wall [ms]", "{:.3f}"),
    ("err_final", "err(T)", "{:.2e}"),
    ("err_max", "max err", "{:.2e}"),
    ("evals", "RHS evals", "{}"),
    ("steps", "steps", "{}"),
    ("status", "status", "{}"),
]


def matched_columns():
    cols = [("contender", "contender", "{}")]
    for target in TARGETS:
        cols.append((f"t_{target:.0e}", f"ms @ {target:.0e}", "{:.3g}"))
    return cols


def report(settings: Settings, load, results) -> str:
    lines = H.machine_lines("lagcodegen work-precision benchmark", load)
    lines += [f"run:      rtol {', '.join(f'{r:.0e}' for r in settings.rtols)}, atol = rtol/100; {N_GRID} output "
              f"times; wall: median of up to {settings.repeats} runs (runs under 0.5 s); budget "
              f"{settings.budget:g} s per contender per scene",
              "errors:   relative per component (|y_i - ref_i| / max_t |ref_i|), max over components; "
              "err(T) at the final time, max err over the grid", ""]
    summary = ["WINNERS (least interpolated time at max err 1e-4, 1e-6, 1e-8; '<=' upper bound)"]
    for scene, rows in results:
        lines += [f"== {scene.key}: {scene.title}", f"   compared: {scene.compared}; reference uncertainty "
                  f"(vs rtol {settings.check_rtol:g}): {scene.ref_unc:.1e}"]
        lines += [f"   {note}" for note in scene.notes]
        lines += [f"   {k}: {v:.2f}" for k, v in scene.setup.items()]
        lines += ["", H.format_table(RUN_COLUMNS, rows), "", "time at matched max error [ms]:", "",
                  H.format_table(matched_columns(), matched_rows(scene, rows)), ""]
        summary.append(f"{scene.key}:")
        summary += winners(scene, rows)
    return "\n".join(lines + [""] + summary) + "\n"


def main(argv=None) -> int:
    args = parse_args(argv)
    settings = settings_from(args)
    start, load_start = time.perf_counter(), H.load_average()
    results = []
    for key in settings.scenes:
        results.append(run_scene(key, settings))
    text = report(settings, (load_start, H.load_average()), results)
    print(text, end="")
    if args.out is not None:
        H.write_report(args.out, "work_precision", text, [r for _, rows in results for r in rows])
        for scene, rows in results:
            H.work_precision_plot(args.out / f"wp_{scene.key}.png", scene.title, curves(rows),
                                  f"max relative error over the grid ({scene.compared})", scene.ref_unc)
        progress(f"wrote {args.out}/work_precision.txt, .csv and wp_<scene>.png")
    progress(f"done in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
