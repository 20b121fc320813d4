"""Ensembles (one C call over a thread pool, bit-identical to single runs), run control (Ctrl-C,
wall-clock limits), pickling and executors (process pool, Dask LocalCluster)."""

import gc
import pickle
import signal
import subprocess
import sys
import textwrap
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen import systems
from lagcodegen.build import driver_sources, find_sundials
from lagcodegen.solvers.ensemble import EnsembleResult

from helpers import STRICT_CFLAGS, cartesian_pendulum, pendulum_q0, run_cvode_main_sanitized

T = np.linspace(0.0, 3.0, 31)


@pytest.fixture(scope="module")
def dpend():
    return lcg.compile_model(systems.double_pendulum(), outputs=["energy"])


@pytest.fixture(scope="module")
def pend():
    return lcg.compile_model(systems.pendulum(), outputs=["energy"])


def members(n=12, seed=1):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.5, 1.5, (n, 2)), rng.uniform(-1, 1, (n, 2)), rng.uniform(9.0, 10.5, n)


def test_members_are_bit_identical_to_single_runs(dpend):
    Q, V, g = members()
    e = dpend.ensemble(T, q0=Q, v0=V, params={"g": g, "l1": 1.1}, threads=2, save="trajectory")
    assert e.status.tolist() == [0] * len(Q) and not e.messages
    for i in range(len(Q)):
        r = dpend.simulate(T, q0=Q[i], v0=V[i], params={"g": g[i], "l1": 1.1})
        m = e.member(i)
        assert np.array_equal(m.y, r.y) and np.array_equal(m.outputs["energy"], r.outputs["energy"])
        assert m.stats["steps"] == r.stats["steps"] and m.stats["rhs_evals"] == r.stats["rhs_evals"]
        assert np.array_equal(e.y[i], r.y[-1])
    final = dpend.ensemble(T, q0=Q, v0=V, params={"g": g, "l1": 1.1}, threads=1)
    assert np.array_equal(final.y, e.y) and final.traj is None
    assert np.array_equal(final.outputs["energy"], e["energy"][:, -1])
    chosen = dpend.ensemble(T, q0=Q, v0=V, params={"g": g, "l1": 1.1}, save=["theta1", "energy"])
    assert chosen.traj.shape == (len(Q), T.size, 2)
    assert np.array_equal(chosen["theta1"], e["theta1"])


def test_method_options_and_band_and_bdf(dpend):
    Q, V, g = members(4)
    for opts in (dict(method="bdf", rtol=1e-7, atol=[1e-9, 1e-9, 1e-8, 1e-8]), dict(linear_solver="fixedpoint"),
                 dict(linear_solver="band"), dict(jacobian=False, max_step=0.05)):
        e = dpend.ensemble(T, q0=Q, v0=V, **opts)
        for i in (0, 3):
            r = dpend.simulate(T, q0=Q[i], v0=V[i], **opts)
            assert np.array_equal(e.y[i], r.y[-1]), opts


def test_failures_are_data(pend):
    q0 = np.array([[0.5], [0.5], [0.5], [3.0]])
    e = pend.ensemble(T, q0=q0, params={"m": [1.0, 0.0, 1.0, 1.0]})
    assert e.status[0] == 0 and e.status[2] == 0
    assert e.status[1] < 0 and e.stats["model_error"][1] == 1 and "singular" in e.messages[1]
    assert set(e.messages) == {1}
    budget = pend.ensemble(T, q0=q0, max_steps=20)
    assert (budget.status == -1).all() and "max_steps" in budget.messages[0]
    assert np.isfinite(budget.y).all() and (budget.t_reached < T[-1]).all()
    slow = pend.ensemble((0.0, 1e7), q0=q0[:2], max_wall=0.05, rtol=1e-12, atol=1e-12, max_steps=10**9)
    assert (slow.status == -81).all() and "wall-clock" in slow.messages[0]
    assert (slow.stats["wall"] < 1.0).all()


def test_member_result_save_and_pickle(tmp_path, pend):
    e = pend.ensemble(T, q0=np.linspace(0.1, 1.0, 5)[:, None], params={"g": 9.0})
    r = e.member(2)
    assert r.t.tolist() == [T[-1]] and r.parameters["g"] == 9.0 and r.success
    path = e.save(tmp_path / "ens.npz")
    data = np.load(path)
    assert np.array_equal(data["y"], e.y) and np.array_equal(data["final_energy"], e.outputs["energy"])
    back = pickle.loads(pickle.dumps(e))
    assert isinstance(back, EnsembleResult) and np.array_equal(back.y, e.y)
    cm = pickle.loads(pickle.dumps(pend))
    assert np.array_equal(cm.ensemble(T, q0=[[0.3]]).y, pend.ensemble(T, q0=[[0.3]]).y)


def test_taylor_members_are_bit_identical(dpend):
    Q, V, _ = members(6)
    e = dpend.ensemble(T, q0=Q, v0=V, method="taylor", save="trajectory", threads=2)
    for i in (0, 5):
        r = dpend.simulate(T, q0=Q[i], v0=V[i], method="taylor")
        assert np.array_equal(e.member(i).y, r.y)


@pytest.mark.parametrize("formulation", ["index1", "ggl", "minimal"])
def test_constrained_ensembles(formulation):
    sim = lcg.compile_constrained(cartesian_pendulum(), formulation=formulation)
    Q = np.array([pendulum_q0(th) for th in np.linspace(0.3, 1.2, 5)])
    Q[2, 0] += 0.1  # inconsistent: rejected, the others run
    V = np.zeros_like(Q)
    e = sim.ensemble(T, q0=Q, v0=V, save="trajectory", threads=2)
    assert e.status.tolist() == [0, 0, -84, 0, 0] and "inconsistent" in e.messages[2]
    for i in (0, 4):
        r = sim.simulate(T, q0=Q[i], v0=V[i])
        m = e.member(i)
        assert np.array_equal(m.y, r.y)
        assert all(np.array_equal(m.outputs[k], r.outputs[k]) for k in m.outputs if k in r.outputs)
    again = pickle.loads(pickle.dumps(sim)).ensemble(T, q0=Q[[0, 1]], v0=V[[0, 1]])
    assert np.array_equal(again.y, e.y[[0, 1]])


def test_process_pool_executor(pend):
    q0 = np.linspace(0.1, 1.5, 23)[:, None]
    g = np.linspace(9.0, 10.0, 23)
    ref = pend.ensemble(T, q0=q0, params={"g": g})
    with ProcessPoolExecutor(2) as ex:
        e = pend.ensemble(T, q0=q0, params={"g": g}, executor=ex, chunk_size=5)
    assert np.array_equal(e.y, ref.y) and e.status.tolist() == ref.status.tolist()
    assert np.array_equal(e.stats["steps"], ref.stats["steps"])


class _Broken:
    """An executor whose futures fail: the chunk's members are marked, nothing raised."""

    def submit(self, fn, *args):
        from concurrent.futures import Future
        f = Future()
        f.set_exception(RuntimeError("worker lost"))
        return f


def test_failed_chunks_are_reported(pend):
    with pytest.raises(lcg.LagcodegenError, match="every chunk"):
        pend.ensemble(T, q0=[[0.1], [0.2]], executor=_Broken(), chunk_size=1)


def test_dask_local_cluster(pend):
    distributed = pytest.importorskip("distributed")
    q0 = np.linspace(0.1, 1.5, 40)[:, None]
    ref = pend.ensemble(T, q0=q0)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=40) as cluster, distributed.Client(cluster) as client:
        e = pend.ensemble(T, q0=q0, executor=client, chunk_size=10)
        # the same simulation again, the first call's scattered copy released meanwhile: each call
        # scatters under a key of its own (a shared, hashed key lost the data: "lost dependencies")
        for _ in range(3):
            del e
            gc.collect()
            e = pend.ensemble(T, q0=q0, executor=client, chunk_size=10)
            assert np.array_equal(e.y, ref.y) and (e.status == 0).all()
    assert np.array_equal(e.y, ref.y) and (e.status == 0).all()


# ---------------------------------------------------------------------- Ctrl-C
LONG_RUN = textwrap.dedent("""
    import sys, numpy as np, lagcodegen as lcg
    from lagcodegen import systems
    kind, method = sys.argv[1], sys.argv[2]
    cm = lcg.compile_model(systems.double_pendulum())
    cm.simulate(np.linspace(0, 1, 11), q0=[1.0, 0.5], v0=[0, 0], method=method)
    print("READY", flush=True)
    try:
        if kind == "single":
            cm.simulate((0, 1e7), q0=[1.0, 0.5], v0=[0, 0], rtol=1e-13, atol=1e-13, max_steps=10**10,
                        method=method)
        else:
            cm.ensemble((0, 1e5), q0=np.tile([1.0, 0.5], (64, 1)), rtol=1e-12, atol=1e-12, max_steps=10**10,
                        threads=2, progress=False, method=method)
    except KeyboardInterrupt as exc:
        res = getattr(exc, "result", None)
        print("INTERRUPTED", type(exc).__name__, "" if res is None else sorted(set(res.status.tolist())),
              flush=True)
        sys.exit(3)
    print("FINISHED", flush=True)
""")


@pytest.mark.parametrize("method", ["adams", "taylor"])
@pytest.mark.parametrize("kind", ["single", "ensemble"])
def test_sigint_stops_a_long_native_run(tmp_path, kind, method):
    """CVODE's driver and the Taylor runtime's: Ctrl-C stops one long run, and the running members
    of an ensemble, within a second or two."""
    script = tmp_path / "long.py"
    script.write_text(LONG_RUN)
    proc = subprocess.Popen([sys.executable, str(script), kind, method], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "READY"
        time.sleep(0.5)
        start = time.perf_counter()
        proc.send_signal(signal.SIGINT)
        line = proc.stdout.readline()  # printed by the KeyboardInterrupt handler
        elapsed = time.perf_counter() - start
        out, err = proc.communicate(timeout=10)
    finally:
        proc.kill()
    assert proc.returncode == 3, line + out + err
    assert "INTERRUPTED" in line and elapsed < 2.0, (line, err, elapsed)
    out = line
    if kind == "ensemble":
        assert "EnsembleInterrupted" in out and "-80" in out


def test_cli_exits_130_on_sigint_without_output(tmp_path):
    model = Path(__file__).resolve().parents[2] / "examples" / "double_pendulum.toml"
    out = tmp_path / "res.csv"
    args = ["simulate", str(model), "-o", str(out), "--t-end", "1e7", "--rtol", "1e-13", "--atol", "1e-13",
            "--max-steps", "1000000000"]
    runner = ("import sys; from lagcodegen.cli import main; print('READY', flush=True); "
              "sys.exit(main(sys.argv[1:]))")
    proc = subprocess.Popen([sys.executable, "-c", runner, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        assert proc.stdout.readline().strip() == "READY"
        time.sleep(3.0)  # deriving, compiling (or the cache), then integrating: Ctrl-C stops either
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=15)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "interrupted" in err
    assert not out.exists() and not list(tmp_path.iterdir())


# ---------------------------------------------------------------------- generated C
SANITIZER_MAIN = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "PREFIX.h"
#include "lcg_cvode.h"

extern const lcg_model PREFIX_model;

int main(void)
{
    enum { M = 40, NT = 21 };
    double y0[M * PREFIXU_NY], p[M * PREFIXU_NP], tout[NT], final[M * (PREFIXU_NY + PREFIXU_NOUT)];
    double traj[M * NT * 2], t_reached[M], wall[M];
    int col[2] = {0, PREFIXU_NY}, flag[M], nt_done[M], i, k, rc;
    long counts[M * 8], member[4];
    char messages[4 * 256];
    lcg_cvode_options opt = {1, 1, 1e-8, 1e-10, NULL, 100000, 0.0, 0.0, 0.0, 0};
    lcg_cvode_ensemble e = {0};

    for (k = 0; k < NT; ++k)
        tout[k] = 0.1 * k;
    for (i = 0; i < M; ++i) {
        for (k = 0; k < PREFIXU_NY; ++k)
            y0[i * PREFIXU_NY + k] = 0.01 * i + 0.1 * k;
        for (k = 0; k < PREFIXU_NP; ++k)
            p[i * PREFIXU_NP + k] = PARAMS[k];
        flag[i] = -82;
    }
    p[3 * PREFIXU_NP + MASS] = 0.0; /* member 3: a zero mass, a singular mass matrix */
    e.model = &PREFIX_model; e.nmem = M; e.nthreads = 3; e.p = p; e.p_stride = PREFIXU_NP; e.y0 = y0; e.y0_stride = PREFIXU_NY;
    e.nt = NT; e.tout = tout; e.final = final; e.traj = traj; e.ncol = 2; e.col = col; e.flag = flag;
    e.nt_done = nt_done; e.t_reached = t_reached; e.wall = wall; e.counts = counts; e.messages = messages;
    e.max_messages = 4; e.message_member = member;
    rc = lcg_cvode_solve_many(&e, &opt);
    for (i = 0, k = 0; i < M; ++i)
        k += flag[i] == 0;
    printf("rc=%d ok=%d done=%ld flag3=%d messages=%ld\n", rc, k, e.done, flag[3], e.n_messages);
    return rc != 0 || k != M - 1 || e.done != M || flag[3] >= 0 || counts[3 * 8 + 5] != 1;
}
"""


def test_ensemble_driver_strict_and_clean_under_sanitizers(tmp_path, cc):
    code = lcg.generate_c(lcg.Scene(lcg.derive(systems.double_pendulum()), outputs=["energy"]))
    run_cvode_main_sanitized(tmp_path, cc, code, SANITIZER_MAIN.replace("MASS", str(code.param_names.index("m1"))))


def test_constrained_and_taylor_ensemble_sources_compile_strictly(tmp_path, cc):
    from lagcodegen.codegen.constrained import generate_constrained
    from lagcodegen.solvers.taylor.ensemble import run_taylor_ensemble  # noqa: F401 - importable
    code, _ = generate_constrained(cartesian_pendulum("ens_strict"), ggl=True)
    code.write(tmp_path)
    for fname, text in driver_sources(code, find_sundials()).items():
        (tmp_path / fname).write_text(text)
    for src in ("lcg_cvc.c", "lcg_ida.c", f"{code.prefix}_dae_table.c"):
        proc = subprocess.run([cc, *STRICT_CFLAGS, "-c", src, "-o", "x.o"], cwd=tmp_path, capture_output=True,
                              text=True)
        assert proc.returncode == 0, proc.stderr


def test_chunks_that_need_the_scene_get_it(dpend, pend):
    """Taylor members on a process pool: the chunks are pickled with the scene (once each), and
    run bit-identically; plain CVODE chunks go without it."""
    from lagcodegen.solvers.cvode import CVODE
    from lagcodegen.solvers.ensemble import needs_scene
    from lagcodegen.solvers.taylor import Taylor
    assert not needs_scene(pend, {"solver": CVODE()})
    assert needs_scene(pend, {"solver": Taylor()}) and needs_scene(pend, {"solver": CVODE(), "events": ["x"]})
    assert needs_scene(pend, {"solver": CVODE(sensitivities=("g",))})
    Q, V, _ = members(6)
    ref = dpend.ensemble(T, q0=Q, v0=V, method="taylor", save="trajectory")
    with ProcessPoolExecutor(2) as ex:
        e = dpend.ensemble(T, q0=Q, v0=V, method="taylor", save="trajectory", executor=ex, chunk_size=3)
    assert np.array_equal(e.y, ref.y) and (e.status == 0).all()
