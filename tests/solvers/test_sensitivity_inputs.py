"""Forward sensitivities on CVODE of runs driven by input tables (lcg_cvsens_solve_inputs): the
damped oscillator m x'' + c x' + k x = u(t) with a piecewise-linear force table, its
sensitivities to k, c and x(0) against central differences of plain input-driven runs, against a
second integrator of the variational equations (scipy's DOP853 on the augmented ODE, segment by
segment between the table's kinks) and dx/dx(0) against its closed form (the free response, the
input dropping out); a direction along the input refused; fitting k and c to a forced response."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import lagcodegen as lcg
from lagcodegen.errors import LagcodegenError

M, K, C = 1.0, 4.0, 0.4
TIMES = [0.0, 1.0, 2.5, 4.0, 6.0]
VALUES = [0.0, 1.5, -0.5, 1.0, 1.0]
DIRECTIONS = ["k", "c", "x(0)"]
X0 = 0.3


def oscillator():
    """m x'' + c x' + k x = F, the force F an input (lagcodegen.systems.forced_oscillator)."""
    return lcg.systems.forced_oscillator("osc_sens_table", m=M, k=K, c=C)


@pytest.fixture(scope="module")
def sim():
    return lcg.compile_model(oscillator(), outputs=["force", "spring"])


@pytest.fixture(scope="module")
def table():
    return lcg.Table(TIMES, VALUES, kind="linear")


def variational_reference(t, table):
    """x and dx/dk, dx/dc, dx/dx(0) of the oscillator from DOP853 on the augmented ODE
    (x, v, s_k, s_k', s_c, s_c', s_x0, s_x0'), restarted at each breakpoint of the table."""
    def f(tt, z):
        x, v, sk, vk, sc, vc, s0, v0 = z
        u = table(tt)
        return [v, (u - C * v - K * x) / M,
                vk, (-x - C * vk - K * sk) / M,
                vc, (-v - C * vc - K * sc) / M,
                v0, (-C * v0 - K * s0) / M]
    edges = [t[0], *[b for b in TIMES if t[0] < b < t[-1]], t[-1]]
    z = np.array([X0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0])
    out = np.empty((t.size, 8))
    for a, b in zip(edges[:-1], edges[1:]):
        sel = (t >= a) & (t <= b)
        sol = solve_ivp(f, (a, b), z, method="DOP853", rtol=1e-12, atol=1e-14, t_eval=t[sel], dense_output=True)
        out[sel] = sol.y.T
        z = sol.sol(b)
    return out[:, 0], out[:, [2, 4, 6]]


def free_response(t):
    """x of the unforced oscillator from x(0) = 1, v(0) = 0: dx/dx(0) of the forced one."""
    w0 = np.sqrt(K / M)
    zeta = C / (2 * np.sqrt(K * M))
    wd = w0 * np.sqrt(1 - zeta ** 2)
    return np.exp(-zeta * w0 * t) * (np.cos(wd * t) + zeta * w0 / wd * np.sin(wd * t))


def test_sensitivities_of_a_table_driven_run(sim, table):
    t = np.linspace(0.0, 8.0, 161)
    x_ref, s_ref = variational_reference(t, table)
    for method in ("adams", "bdf"):
        res = sim.simulate(t, q0=[X0], inputs={"F": table}, rtol=1e-10, atol=1e-12, method=method,
                           sensitivities=DIRECTIONS)
        assert res.success and res.stats["restarts"] == 3  # the kinks at 1, 2.5 and 4
        assert np.max(np.abs(res["x"] - x_ref)) < 1e-8
        for j, name in enumerate(DIRECTIONS):
            s = res.sensitivity("x", name)
            assert np.max(np.abs(s - s_ref[:, j])) < 2e-8 * np.max(np.abs(s_ref[:, j])), (method, name)
        assert np.max(np.abs(res.sensitivity("x", "x(0)") - free_response(t))) < 1e-8
        # outputs: the force is the table at every output time and depends on no direction; the
        # spring's k x has d/dk = x + k dx/dk
        assert np.allclose(res["force"], table(t), rtol=0, atol=1e-14)
        assert np.all(res.sensitivity("force", "k") == 0.0)
        assert np.max(np.abs(res.sensitivity("spring", "k") - (res["x"] + K * res.sensitivity("x", "k")))) < 1e-12
        # the restarts at the kinks (CVodeReInit of the augmented state) spare rejected steps
        straddled = sim.simulate(t, q0=[X0], inputs={"F": lcg.Table(TIMES, VALUES, restart=False)}, rtol=1e-10,
                                 atol=1e-12, method=method, sensitivities=DIRECTIONS)
        assert np.max(np.abs(straddled.sensitivities - res.sensitivities)) < 1e-6
        assert 2 * res.stats["err_test_fails"] < straddled.stats["err_test_fails"]
    # the forced run differs from the free one: the table does act in the sensitivity run
    free = sim.simulate(t, q0=[X0], rtol=1e-10, atol=1e-12, sensitivities=["k"])
    assert np.max(np.abs(free.sensitivity("x", "k") - s_ref[:, 0])) > 0.1


def central_differences(sim, t, opts) -> dict:
    """(direction, value) -> the central difference (step 1e-4 relative) of x, x_dot and the
    output "spring" of plain runs with ``opts``, along k, c and x(0)."""
    out = {}
    for name, base in (("k", K), ("c", C), ("x(0)", X0)):
        h = 1e-4 * max(abs(base), 1.0)
        runs = []
        for sign in (1, -1):
            if name == "x(0)":
                runs.append(sim.simulate(t, q0=[X0 + sign * h], **opts))
            else:
                runs.append(sim.simulate(t, q0=[X0], params={name: base + sign * h}, **opts))
        for value in ("x", "x_dot", "spring"):
            out[name, value] = (runs[0][value] - runs[1][value]) / (2 * h)
    return out


@pytest.mark.parametrize("method, tolerances, x_bound, bound", [
    ("adams", dict(rtol=1e-11, atol=1e-13), 1e-9, 1e-6),
    ("taylor", dict(rtol=1e-12, atol=1e-14), 1e-10, 1e-7),
])
def test_sensitivities_match_central_differences_of_plain_runs(sim, table, method, tolerances, x_bound, bound):
    """Each family's sensitivities of a table-driven run against central differences of its own
    plain table-driven runs."""
    t = np.linspace(0.0, 8.0, 81)
    opts = dict(inputs={"F": table}, method=method, **tolerances)
    res = sim.simulate(t, q0=[X0], sensitivities=DIRECTIONS, **opts)
    plain = sim.simulate(t, q0=[X0], **opts)
    assert np.max(np.abs(res["x"] - plain["x"])) < x_bound
    for (name, value), cd in central_differences(sim, t, opts).items():
        s = res.sensitivity(value, name)
        assert np.max(np.abs(s - cd)) < bound * max(np.max(np.abs(cd)), 1.0), (name, value)


def test_simultaneous_corrector_and_restarts_at_output_times(sim, table):
    """The simultaneous corrector agrees with the staggered one; output times on and off the
    breakpoints give the same values as a grid without them."""
    t = np.array([0.0, 1.0, 1.7, 2.5, 3.2, 4.0, 7.0])
    a = sim.simulate(t, q0=[X0], inputs={"F": table}, rtol=1e-10, atol=1e-12, sensitivities=DIRECTIONS)
    b = sim.simulate(t, q0=[X0], inputs={"F": table}, rtol=1e-10, atol=1e-12, sensitivities=DIRECTIONS,
                     sensitivity_corrector="simultaneous")
    x_ref, s_ref = variational_reference(t, table)
    for res in (a, b):
        assert np.max(np.abs(res["x"] - x_ref)) < 1e-8
        assert np.max(np.abs(res.sensitivities[:, :, 0] - s_ref)) < 1e-7 * np.max(np.abs(s_ref))


def test_a_direction_along_an_input_is_refused(sim, table):
    t = np.linspace(0.0, 2.0, 5)
    with pytest.raises(LagcodegenError, match="'F' is an input driven by a table"):
        sim.simulate(t, q0=[X0], inputs={"F": table}, sensitivities=["k", "F"])
    # without a table F is a run-time parameter like any other: d x/d F of a constant force
    res = sim.simulate(t, q0=[X0], rtol=1e-10, atol=1e-12, sensitivities=["F"])
    assert np.max(np.abs(res.sensitivity("x", "F") - (1 - free_response(t)) / K)) < 1e-8
    # that call's values learned by simulate()'s fast path: the same call with a table is not taken
    # for it (the tables go the full path, here refused again)
    again = sim.simulate(t, q0=[X0], rtol=1e-10, atol=1e-12, sensitivities=["F"])
    assert np.array_equal(again.sensitivities, res.sensitivities)
    with pytest.raises(LagcodegenError, match="'F' is an input driven by a table"):
        sim.simulate(t, q0=[X0], rtol=1e-10, atol=1e-12, sensitivities=["F"], inputs={"F": table})
    with pytest.raises(LagcodegenError, match="'F' is an input driven by a table"):
        sim.ensemble(t, q0=np.full((2, 1), X0), inputs={"F": table}, sensitivities=["k", "F"])
    with pytest.raises(LagcodegenError, match="'F' is an input driven by a table"):
        sim.simulate(t, q0=[X0], inputs={"F": table}, sensitivities=["F", "k"], method="taylor")


def test_fit_of_a_table_driven_oscillator(sim, table):
    """k and c recovered from the forced response (1e-3 noise, seeded) within 3 standard
    deviations; the fit runs simulate with the tables at each evaluation."""
    t = np.linspace(0.0, 8.0, 121)
    truth = sim.simulate(t, q0=[X0], inputs={"F": table}, rtol=1e-10, atol=1e-12)["x"]
    noise = 1e-3
    data = truth + noise * np.random.default_rng(7).standard_normal(t.size)
    fit = lcg.fit(sim, t, data[:, None], params={"k": 3.5, "c": 0.3}, observe=["x"], q0=[X0], sigma=noise,
                  inputs={"F": table}, rtol=1e-10, atol=1e-12)
    assert fit.success and fit.iterations <= 20
    for name, value in (("k", K), ("c", C)):
        assert abs(fit.params[name] - value) < 3 * fit.stderr[name], (name, fit.params[name], fit.stderr[name])
        assert fit.stderr[name] < 0.05 * value


SANITIZE_MAIN = r"""
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>

#include "lcg_cvsens.h"

int osc_sens_table_sens_rhs(double t, const double *y, const double *p, int ns, const int *which, const double *s,
                            double *ydot, double *sdot);
int osc_sens_table_sens_outputs(double t, const double *y, const double *p, int ns, const int *which,
                                const double *s, double *dout);
extern const lcg_model osc_sens_table_model;

#define NT 17
#define NS 3
static const double P[4] = {1.0, 4.0, 0.4, 123.0}; /* m, k, c, F (F: overwritten by the table) */
static const double TT[5] = {0.0, 1.0, 2.5, 4.0, 6.0}, TV[5] = {0.0, 1.5, -0.5, 1.0, 1.0};
static const double BREAKS[3] = {1.0, 2.5, 4.0};

typedef struct { int which[NS]; double yout[NT * 2], sout[NT * NS * 2], out[NT * 2], dout[NT * NS * 2];
                 int flag; lcg_cvsens_stats st; } job;

static lcg_inputs inputs;

static void *run(void *arg)
{
    job *j = (job *)arg;
    double tout[NT], y0[2] = {0.3, 0.0}, s0[NS * 2], atol[2 * (1 + NS)];
    lcg_cvsens_options opt;
    int k;
    for (k = 0; k < NT; ++k)
        tout[k] = 0.5 * k;
    memset(s0, 0, sizeof s0);
    for (k = 0; k < NS; ++k)
        if (j->which[k] < 0)
            s0[2 * k] = 1.0;
    for (k = 0; k < 2 * (1 + NS); ++k)
        atol[k] = 1e-12;
    memset(&opt, 0, sizeof opt);
    opt.method = 1;
    opt.rtol = 1e-10;
    opt.atol = atol;
    opt.max_steps = 100000;
    opt.jacobian = 1;
    j->flag = lcg_cvsens_solve_inputs(&osc_sens_table_model, osc_sens_table_sens_rhs, osc_sens_table_sens_outputs,
                                      P, &inputs, NS, j->which, y0, s0, NT, tout, j->yout, j->sout, j->out,
                                      j->dout, &opt, &j->st);
    return NULL;
}

int main(void)
{
    lcg_input_table tab, bad;
    double c[4 * 6];
    job a, b, r;
    pthread_t ta, tb;
    int k;
    if (lcg_input_table_fill(&tab, 3, 5, TT, TV, 1, c) != 0)
        return 1;
    inputs.count = 1;
    inputs.tables = &tab;
    inputs.nbreak = 3;
    inputs.breaks = BREAKS;
    memset(&a, 0, sizeof a);
    a.which[0] = 1; a.which[1] = 2; a.which[2] = -1;  /* k, c, x(0) */
    b = a;
    pthread_create(&ta, NULL, run, &a);  /* two runs at once: each its own copy of p */
    pthread_create(&tb, NULL, run, &b);
    pthread_join(ta, NULL);
    pthread_join(tb, NULL);
    printf("%d %d %ld %d\n", a.flag, a.st.nt_done, a.st.nsteps,
           memcmp(a.sout, b.sout, sizeof a.sout) == 0 && memcmp(a.yout, b.yout, sizeof a.yout) == 0);
    for (k = 0; k < NT * 2; ++k)
        printf("%.17g ", a.yout[k]);
    printf("\n");
    for (k = 0; k < NT * NS * 2; ++k)
        printf("%.17g ", a.sout[k]);
    printf("\n");
    for (k = 0; k < NT * 2; ++k)
        printf("%.17g ", a.out[k]);
    printf("\n");
    r = a;
    r.which[1] = 3;  /* along F, the input */
    run(&r);
    printf("%d %s\n", r.flag, r.st.message);
    bad = tab;
    bad.slot = 7;  /* no such parameter */
    inputs.tables = &bad;
    r.which[1] = 2;
    run(&r);
    printf("%d %s\n", r.flag, r.st.message);
    return 0;
}
"""


def test_inputs_path_runs_clean_under_sanitizers(tmp_path, cc, sim):
    """lcg_cvsens_solve_inputs under ASan/UBSan (leaks too): two runs on two threads at once (the
    same numbers bit for bit: each its own copy of p) matching simulate's, a direction along the
    input and a table of a slot out of range refused with LCG_FLAG_BAD_INPUT and the reason."""
    import subprocess

    from lagcodegen.build import find_sundials, table_source
    from lagcodegen.codegen.sensitivity import sensitivity_source
    from lagcodegen.solvers.cvode.sensitivity import _sources
    files = {**sim.code.files, **table_source(sim.code), **sensitivity_source(sim.code.scene, sim.code.prefix),
             **_sources(), "main.c": SANITIZE_MAIN}
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    units = sorted(n for n in files if n.endswith(".c"))
    san = ["-std=c99", "-g", "-O1", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
    proc = subprocess.run([cc, *san, "-I.", *units, "-o", "run", *find_sundials().link_args(), "-lm", "-pthread"],
                          cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    env = {"ASAN_OPTIONS": "detect_leaks=1", "PATH": "/usr/bin:/bin"}
    out = subprocess.run(["./run"], cwd=tmp_path, capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stdout + out.stderr
    head, ys, ss, outs, along, bad = out.stdout.splitlines()
    flag, done, steps, same = map(int, head.split())
    assert flag == 0 and done == 17 and steps > 50 and same == 1
    t = 0.5 * np.arange(17)
    res = sim.simulate(t, q0=[X0], inputs={"F": lcg.Table(TIMES, VALUES)}, rtol=1e-10, atol=1e-12,
                       sensitivities=DIRECTIONS)
    assert np.max(np.abs(np.array(ys.split(), dtype=float).reshape(17, 2) - res.y)) < 1e-9
    s = np.array(ss.split(), dtype=float).reshape(17, 3, 2)
    assert np.max(np.abs(s - res.sensitivities[:, :, :2])) < 1e-8
    assert np.array_equal(np.array(outs.split(), dtype=float).reshape(17, 2)[:, 0], res["force"])
    assert along.startswith("-22 ") and "direction 1 is along run-time parameter 3" in along
    assert bad.startswith("-22 ") and "slot 7 out of range" in bad
