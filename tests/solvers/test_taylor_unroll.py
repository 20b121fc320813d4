"""The Taylor jet with its first orders written out (lagcodegen.codegen.taylor.unroll) against the
loop over the orders, and against series coefficients computed by sympy."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.derivation import derive
from lagcodegen.formulation.scene import Scene
from lagcodegen.model.events import Event
from lagcodegen.codegen.taylor import emit
from lagcodegen.codegen.taylor.decompose import decompose
from lagcodegen.codegen.taylor.emit import jet_sources, taylor_code
from lagcodegen.codegen.taylor.unroll import MAX_TERMS, UNROLL_ORDERS, pairwise, terms
from lagcodegen.solvers.taylor import build_taylor
from lagcodegen.theory.routhian import reduce as routh_reduce

from .test_taylor import all_operations_model

MARK = "written out, each Cauchy sum a balanced tree"


def both_forms(monkeypatch, scene, events=()):
    """The Taylor integrator of ``scene`` built with the orders written out and with the loop."""
    monkeypatch.setattr(emit, "MAX_TERMS", 10**9)
    unrolled = build_taylor(scene, events=events)
    text = jet_sources(scene, events)
    monkeypatch.setattr(emit, "MAX_TERMS", -1)
    looped = build_taylor(scene, events=events)
    assert MARK in next(v for k, v in text.items() if k.endswith("_jet.c"))
    assert MARK not in next(v for k, v in jet_sources(scene, events).items() if k.endswith("_jet.c"))
    monkeypatch.undo()
    return unrolled, looped


def test_pairwise_sum_is_a_balanced_tree():
    assert pairwise([]) == "0.0"
    assert pairwise(["a"]) == "a"
    assert pairwise(["a", "b", "c", "d", "e"]) == "(((a + b) + (c + d)) + e)"


@pytest.mark.parametrize("model, y0", [(all_operations_model(), [0.3, -0.4]),
                                       (lcg.systems.double_pendulum(), [0.9, -0.5, 0.4, 1.1])])
def test_every_operation_and_a_full_mass_matrix_agree_with_the_loop(monkeypatch, model, y0):
    """Every operation kind (all_operations_model: a diagonal mass matrix depending on x, the
    time t in the forces) and a full mass matrix solved at every order (the double pendulum):
    the jet to order 26, past the written-out orders into the loop's, equals the loop's to
    rounding (the sums are the same terms in another order), and so do whole runs."""
    sc = Scene(derive(model), jacobian=False)
    unrolled, looped = both_forms(monkeypatch, sc)
    p = np.array(sc.default_parameters(), dtype=float)
    y0 = np.array(y0)
    order = UNROLL_ORDERS + 3
    a, b = unrolled.jet(0.7, y0, p, order), looped.jet(0.7, y0, p, order)
    assert not np.array_equal(a, b)  # another order of summation: not the same code
    scale = np.abs(b).max(axis=1, keepdims=True) * 1.5 ** np.arange(order + 1)  # coefficients decay
    assert np.abs(a - b).max() <= 1e-13 * np.abs(b).max()
    assert np.all(np.abs(a - b) <= 1e-12 * scale)
    t = np.linspace(0.0, 3.0, 7)
    ra, rb = (m.simulate(t, y0, p, rtol=1e-11, atol=1e-11) for m in (unrolled, looped))
    assert ra.status == rb.status == 0 and ra.stats["steps"] > 5
    assert np.abs(ra.y - rb.y).max() < 1e-9


def test_series_coefficients_of_the_written_out_jet(monkeypatch):
    """The written-out jet of every operation kind against sympy's series of the same model
    (test_taylor.test_every_recurrence_against_series_coefficients checks the loop's)."""
    sc = Scene(derive(all_operations_model()), jacobian=False)
    assert terms(decompose(sc)) > MAX_TERMS  # built with the loop by default
    monkeypatch.setattr(emit, "MAX_TERMS", 10**9)
    assert MARK in next(v for k, v in jet_sources(sc).items() if k.endswith("_jet.c"))
    tm = build_taylor(sc)
    p = np.array(sc.default_parameters(), dtype=float)
    ref = [0.3, -0.4, -0.04686657238087328, 0.08188876274720655, 0.0033666767926870496,
           -0.005741180512428886, -0.0003421140497075111, 0.00040147483794182565, 5.684598823569504e-05]
    jet = tm.jet(0.7, np.array([0.3, -0.4]), p, 8)
    assert np.abs(jet[0] - ref).max() < 1e-16
    assert np.abs(jet[1, :8] - np.arange(1, 9) * np.array(ref[1:])).max() < 1e-15


def test_small_models_are_written_out_and_larger_ones_loop(monkeypatch):
    """The pendulum (one sin/cos pair) is written out; the double pendulum, whose written-out
    orders would not fit a processor's instruction cache, keeps the loop. With events (one order
    more of the operations), the pendulum's runs and event times equal the loop's to rounding."""
    pend = Scene(derive(lcg.systems.pendulum()), jacobian=False)
    assert terms(decompose(pend)) <= MAX_TERMS
    assert MARK in next(v for k, v in jet_sources(pend).items() if k.endswith("_jet.c"))
    dp = Scene(derive(lcg.systems.double_pendulum()), jacobian=False)
    assert terms(decompose(dp)) > MAX_TERMS
    assert MARK not in next(v for k, v in jet_sources(dp).items() if k.endswith("_jet.c"))
    events = [Event("down", sp.Symbol("theta"), 0, False)]
    unrolled, looped = both_forms(monkeypatch, pend, events)
    p = np.array(pend.default_parameters(), dtype=float)
    t = np.linspace(0.0, 10.0, 11)
    ra, rb = (m.simulate(t, np.array([1.0, 0.0]), p, rtol=1e-12, atol=1e-12) for m in (unrolled, looped))
    assert ra.status == rb.status == 0
    assert np.abs(ra.y - rb.y).max() < 1e-11
    ta, tb = (np.array([e.t for e in r.events if e.name == "down"]) for r in (ra, rb))
    assert len(ta) == len(tb) >= 4
    assert np.abs(ta - tb).max() < 1e-11


PENDULUM_MAIN = r"""
#include <stdio.h>
#include "pendulum_taylor.h"

int main(void)
{
    double p[3] = {1.0, 9.81, 1.0}, y0[2] = {1.0, 0.0}, t[3] = {0.0, 5.0, 10.0}, yout[6], out[3];
    double et[16], ey[32];
    int which[16], dir[16], order, flag = 0;
    for (order = 0; order <= 28; order += 28) { /* the rule's order (written out), then past the written-out ones */
        pendulum_taylor_options opt = {1e-10, 1e-10, 0, 100000, 0.0, order};
        pendulum_taylor_stats st;
        pendulum_taylor_events ev = {16, 0, et, ey, which, dir, 0};
        flag |= pendulum_taylor_solve(p, y0, 3, t, yout, out, &opt, &st, &ev);
        printf("%d %d %ld %d %.17g\n", flag, st.order, st.nsteps, ev.n_events, yout[4]);
    }
    return flag;
}
"""


def test_written_out_jets_compile_strictly_and_run_clean_under_sanitizers(tmp_path, cc):
    """Written-out jets (the pendulum with an event, a Routhian's quadrature state): no warning
    under -Wall -Wextra -Werror -std=c99 -pedantic; the pendulum's integrator runs clean under
    ASan/UBSan at the rule's order (every order written out, one more for the event) and at order
    28 (past them, into the loop), with the same events and final state."""
    events = [Event("down", sp.Symbol("theta"), 0, False)]
    red = routh_reduce(lcg.systems.central_potential())
    for scene, ev in [(Scene(derive(lcg.systems.pendulum()), jacobian=False, outputs=["energy"]), events),
                      (Scene(red.eom, jacobian=False, outputs=["jacobi_h"]), [])]:
        code, _, _ = taylor_code(scene, events=ev)
        code.write(tmp_path)
        assert MARK in (tmp_path / f"{code.prefix}_taylor.c").read_text()
        proc = subprocess.run([cc, "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic", "-O2", "-c",
                               f"{code.prefix}_taylor.c", "-o", f"{code.prefix}.o"], cwd=tmp_path, capture_output=True,
                              text=True)
        assert proc.returncode == 0, proc.stderr
    (tmp_path / "main.c").write_text(PENDULUM_MAIN)
    proc = subprocess.run([cc, "-std=c99", "-g", "-O1", "-fsanitize=address,undefined", "-fno-sanitize-recover=all",
                           "main.c", "pendulum_taylor.c", "-o", "run", "-lm"], cwd=tmp_path, capture_output=True,
                          text=True)
    assert proc.returncode == 0, proc.stderr
    run = subprocess.run(["./run"], cwd=tmp_path, capture_output=True, text=True,
                         env={"ASAN_OPTIONS": "detect_leaks=1", "PATH": "/usr/bin:/bin"})
    assert run.returncode == 0, run.stdout + run.stderr
    (f1, o1, n1, e1, y1), (f2, o2, n2, e2, y2) = (line.split() for line in run.stdout.splitlines())
    assert int(f1) == int(f2) == 0 and int(o1) == 15 and int(o2) == 28
    assert int(e1) == int(e2) >= 4 and abs(float(y1) - float(y2)) < 1e-9
