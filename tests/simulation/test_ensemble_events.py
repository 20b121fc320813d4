"""Every event recorded per ensemble member (issue 39): on CVODE's ODE pool driver, index-1 CVODE,
GGL IDA, the sensitivity ensembles (CVODE and Taylor) and executor chunks, each member's
``member(i).events`` are the records of the same member's single ``simulate`` run, bit for bit;
beyond ``max_events`` (64 per member by default) the events dropped are counted per member."""

from __future__ import annotations

import math
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest
from scipy.special import ellipk

import lagcodegen as lcg

from helpers import cartesian_pendulum, pendulum_q0, run_cvode_main_sanitized

G, L = 9.81, 1.0
TIGHT = dict(rtol=1e-10, atol=1e-12)


def period(theta0: float, l: float = L, g: float = G) -> float:
    """4 K(k) sqrt(l/g), k = sin(theta0/2): the pendulum released at rest from theta0."""
    return 4 * ellipk(math.sin(theta0 / 2) ** 2) * math.sqrt(l / g)


def same_records(got: list, want: list) -> None:
    """The two lists of EventRecords are equal field by field, bit for bit."""
    assert len(got) == len(want)
    for a, b in zip(got, want):
        assert (a.name, a.index, a.t, a.direction, a.terminal) == (b.name, b.index, b.t, b.direction, b.terminal)
        assert a.y.dtype == b.y.dtype and a.y.shape == b.y.shape and np.array_equal(a.y, b.y)
        assert a.state_names == b.state_names


@pytest.fixture(scope="module")
def pend():
    return lcg.compile_model(lcg.systems.pendulum("ens_ev_pend"), outputs=["energy"])


#: theta = 0 crossed either way (not terminal), and a stop at the first turning point after
#: the second crossing: theta_dot increasing through 0 at theta = -theta0 ... (terminal)
EVENTS = [lcg.Event("cross", "theta", 0, False), lcg.Event("turn", "theta_dot", 1, True)]


def test_ode_members_record_their_events_as_single_runs(pend):
    """Every member (its own theta0 and g, 2 threads) records the crossing at T/4 and the
    terminal turning point at T/2: its events those of its run alone; the counts agree and
    nothing is dropped."""
    theta0 = np.array([0.3, 1.0, 2.0, 2.8, 0.05])
    g = np.array([9.81, 9.0, 10.2, 9.81, 9.5])
    ens = pend.ensemble([0, 20], q0=theta0[:, None], params={"g": g}, events=EVENTS, threads=2, **TIGHT)
    assert (ens.status == 0).all()
    assert list(ens.stats["events"]) == [2] * 5 and list(ens.stats["events_dropped"]) == [0] * 5
    for i in range(len(theta0)):
        alone = pend.simulate([0, 20], q0=[theta0[i]], params={"g": g[i]}, events=EVENTS, **TIGHT)
        m = ens.member(i)
        same_records(m.events, alone.events)
        cross, turn = m.events
        T = period(theta0[i], g=g[i])
        assert cross.name == "cross" and not cross.terminal and abs(cross.t - T / 4) < 1e-8 * T
        assert turn.name == "turn" and turn.terminal and abs(turn.t - T / 2) < 1e-8 * T
        assert ens.t_reached[i] == turn.t


def test_members_beyond_max_events_count_the_dropped(pend):
    """Over 10 s a member swinging from theta0 crosses theta = 0 floor(10 / (T/2) + 1/2) times; with
    max_events=3 each member keeps the first 3 of its run alone's and reports the rest dropped;
    by default (64 per member) a member with more than 64 crossings drops its excess."""
    crossing = [lcg.Event("cross", "theta", 0, False)]
    theta0 = np.array([0.5, 2.9])
    few = pend.ensemble([0, 10], q0=theta0[:, None], events=crossing, max_events=3, threads=2, **TIGHT)
    for i, a in enumerate(theta0):
        alone = pend.simulate([0, 10], q0=[a], events=crossing, **TIGHT)
        n = math.floor(10 / (period(a) / 2) + 0.5)
        assert len(alone.events) == n > 3
        same_records(few.member(i).events, alone.events[:3])
        assert few.stats["events"][i] == n and few.stats["events_dropped"][i] == n - 3
        assert few.member(i).stats["events_dropped"] == n - 3
    long = pend.ensemble([0, 80], q0=[[0.5], [2.9]], events=crossing, threads=2, **TIGHT)
    counts = [math.floor(80 / (period(a) / 2) + 0.5) for a in theta0]
    assert counts[0] > 64 > counts[1]
    assert list(long.stats["events"]) == counts
    assert list(long.stats["events_dropped"]) == [counts[0] - 64, 0]
    alone = pend.simulate([0, 80], q0=[0.5], events=crossing, **TIGHT)
    same_records(long.member(0).events, alone.events[:64])
    assert len(long.member(1).events) == counts[1]


def test_ensembles_with_sensitivities_record_events(pend):
    """CVODE and Taylor ensembles with sensitivities and events: each member's records (and each
    event's time sensitivity) are its run alone's."""
    q0 = np.array([[0.5], [1.2], [-0.3]])
    names = ["l", "theta(0)"]
    for method in ("bdf", "taylor"):
        ens = pend.ensemble([0, 20], q0=q0, events=EVENTS, sensitivities=names, method=method, threads=2, **TIGHT)
        assert list(ens.stats["events_dropped"]) == [0, 0, 0]
        for i in range(3):
            alone = pend.simulate([0, 20], q0=q0[i], events=EVENTS, sensitivities=names, method=method, **TIGHT)
            got = ens.member(i).events
            same_records(got, alone.events)
            assert len(got) >= 2 and got[-1].terminal and ens.stats["events"][i] == alone.stats["events"]
        one = pend.ensemble([0, 20], q0=q0, events=EVENTS, sensitivities=names, method=method, max_events=1, **TIGHT)
        for i in range(3):  # the first event kept, the others counted dropped
            same_records(one.member(i).events, ens.member(i).events[:1])
            assert one.stats["events_dropped"][i] == ens.stats["events"][i] - 1 > 0
            assert [e.t_sensitivity for e in got] == [e.t_sensitivity for e in alone.events]


@pytest.mark.parametrize("formulation", ["index1", "ggl", "minimal"])
def test_constrained_members_record_their_compiled_events(formulation):
    """The Cartesian pendulum with its compiled events (theta = 0.7 crossed either way, not
    terminal; theta >= 0.4 as an inequality: terminal where it comes down to 0.4): each member's
    events those of its run alone, on index-1 CVODE, GGL IDA and in minimal coordinates (y
    eliminated: the events on the branch's ODE); a member rejected at its initial
    state has none."""
    cs = cartesian_pendulum(f"ens_ev_{formulation}")
    x, y = cs.model.coords
    bounded = lcg.ConstrainedSystem(cs.model, holonomic=cs.holonomic, inequalities=[y + L * math.cos(0.4)])
    more = dict(eliminate=["y"]) if formulation == "minimal" else {}
    sim = lcg.compile_constrained(bounded, formulation=formulation,
                                  events=[lcg.Event("cross", y + L * math.cos(0.7), 0, False)], **more)
    Q = np.array([pendulum_q0(a) for a in (0.5, 0.8, 1.2, 0.6)])
    Q[3, 0] += 0.1  # inconsistent: rejected
    V = np.zeros_like(Q)
    ens = sim.ensemble([0, 5], q0=Q, v0=V, threads=2, **TIGHT)
    assert ens.status.tolist() == [0, 0, 0, -84]
    assert ens.member(3).events == [] and ens.stats["events"][3] == 0
    for i in range(3):
        alone = sim.simulate([0, 5], q0=Q[i], v0=V[i], **TIGHT)
        same_records(ens.member(i).events, alone.events)
        assert ens.stats["events"][i] == len(alone.events) and ens.stats["events_dropped"][i] == 0
    assert [e.name for e in ens.member(0).events] == ["ineq_0"]  # 0.5 never reaches 0.7
    for i in (1, 2):
        assert [e.name for e in ens.member(i).events] == ["cross", "ineq_0"]
        cross, stop = ens.member(i).events
        assert not cross.terminal and stop.terminal and cross.t < stop.t
        assert abs(abs(cross.q["x"]) - L * math.sin(0.7)) < 1e-9 and abs(abs(stop.q["x"]) - L * math.sin(0.4)) < 1e-9


def test_executor_chunks_carry_every_members_events(pend):
    """Chunks on a process pool: each member's events, dropped counts and stats are those of the
    ensemble in one call."""
    theta0 = np.linspace(0.4, 2.6, 7)
    ref = pend.ensemble([0, 20], q0=theta0[:, None], events=EVENTS, threads=1, **TIGHT)
    with ProcessPoolExecutor(2) as ex:
        ens = pend.ensemble([0, 20], q0=theta0[:, None], events=EVENTS, executor=ex, chunk_size=3, **TIGHT)
    assert (ens.status == 0).all()
    assert np.array_equal(ens.stats["events_dropped"], ref.stats["events_dropped"])
    for i in range(len(theta0)):
        same_records(ens.member(i).events, ref.member(i).events)


def test_contact_ensembles_count_the_events_beyond_max_events():
    """A bouncing ball (e = 0.8) with its apex as a compiled event: with max_events=2 a member
    keeps its run alone's first two apexes (the same run: max_events=2 too) and reports the
    others found as dropped; its run without the bound finds them all."""
    import sympy as sp
    m = lcg.Model("ens_ev_ball")
    (y,) = m.coordinates("y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    apex = lcg.Event("apex", sp.Symbol("y_dot"), direction=-1, terminal=False)
    ball = lcg.compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=0.8)]),
                                   "index1", events=[apex])
    h0 = np.array([1.0, 0.4])
    t = np.linspace(0, 3, 31)
    ens = ball.ensemble(t, q0=h0[:, None], v0=np.zeros((2, 1)), max_events=2, threads=2, **TIGHT)
    for i in range(2):
        few = ball.simulate(t, q0=[h0[i]], v0=[0.0], max_events=2, **TIGHT)
        every = ball.simulate(t, q0=[h0[i]], v0=[0.0], **TIGHT)
        same_records(ens.member(i).events, few.events)
        same_records(ens.member(i).events, every.events[:2])
        assert len(every.events) > 2
        assert ens.stats["events"][i] == len(every.events) and ens.stats["events_dropped"][i] == len(every.events) - 2


def test_saved_ensembles_keep_every_members_events(pend, tmp_path):
    """``save`` writes each member's events as flat arrays: read back, member i's entries are its
    records."""
    theta0 = np.array([0.4, 1.5, 2.2])
    ens = pend.ensemble([0, 20], q0=theta0[:, None], events=EVENTS, **TIGHT)
    data = np.load(ens.save(tmp_path / "ens.npz"))
    for i in range(len(theta0)):
        mine = data["event_member"] == i
        recs = ens.member(i).events
        assert data["event_name"][mine].tolist() == [r.name for r in recs]
        assert data["event_t"][mine].tolist() == [r.t for r in recs]
        assert data["event_direction"][mine].tolist() == [r.direction for r in recs]
        assert data["event_terminal"][mine].tolist() == [r.terminal for r in recs]
        assert np.array_equal(data["event_y"][mine], np.array([r.y for r in recs]))
    assert data["event_y"].shape == (6, 2) and data["stats_events_dropped"].tolist() == [0, 0, 0]


def test_taylor_members_record_their_events_as_single_runs(pend):
    """Taylor ensembles with events (no sensitivities): each member the run of the jet with its
    events that ``simulate(method="taylor")`` makes of it alone: its events, trajectory, final
    state and counts bit for bit; the crossing at T/4 and the terminal turn at T/2; max_events
    bounds what a member keeps and the rest is counted dropped."""
    theta0 = np.array([0.3, 1.0, 2.0, 2.8])
    t = np.linspace(0, 20, 41)
    ens = pend.ensemble(t, q0=theta0[:, None], events=EVENTS, method="taylor", save="trajectory", threads=2, **TIGHT)
    assert (ens.status == 0).all() and list(ens.stats["events_dropped"]) == [0] * 4
    for i, a in enumerate(theta0):
        alone = pend.simulate(t, q0=[a], events=EVENTS, method="taylor", **TIGHT)
        m = ens.member(i)
        same_records(m.events, alone.events)
        assert ens.t_reached[i] == alone.t[-1] == alone.events[-1].t and np.array_equal(ens.y[i], alone.y[-1])
        rows = int(ens.nt_done[i])
        assert np.array_equal(m.y, alone.y[:rows]) and ens.stats["steps"][i] == alone.stats["steps"]
        T = period(a)
        assert abs(m.events[0].t - T / 4) < 1e-8 * T and abs(m.events[1].t - T / 2) < 1e-8 * T
    crossing = [lcg.Event("cross", "theta", 0, False)]
    few = pend.ensemble([0, 10], q0=theta0[:, None], events=crossing, method="taylor", max_events=3, **TIGHT)
    for i, a in enumerate(theta0):
        alone = pend.simulate([0, 10], q0=[a], events=crossing, method="taylor", **TIGHT)
        assert len(alone.events) > 3
        same_records(few.member(i).events, alone.events[:3])
        assert few.stats["events"][i] == len(alone.events) and few.stats["events_dropped"][i] == len(alone.events) - 3


# ---------------------------------------------------------------------- the pool's records in C
EVENTS_MAIN = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "PREFIX.h"
#include "lcg_cvode.h"

extern const lcg_model PREFIX_model;

static int theta1(double t, const double *y, const double *p, double *gout)
{
    (void)t;
    (void)p;
    gout[0] = y[0];
    return 0;
}

int main(void)
{
    enum { M = 24, NT = 11, MAXEV = 2 };
    double y0[M * PREFIXU_NY], p[M * PREFIXU_NP], tout[NT], final[M * (PREFIXU_NY + PREFIXU_NOUT)];
    double t_reached[M], ev_t[M * MAXEV], ev_y[M * MAXEV * PREFIXU_NY];
    int flag[M], nt_done[M], ev_which[M * MAXEV], ev_dir[M * MAXEV], rootdir[1] = {0}, terminal[1] = {0};
    int i, k, bad = 0, dropping = 0;
    long counts[M * 8];
    lcg_cvode_options opt = {1, 1, 1e-10, 1e-12, NULL, 100000, 0.0, 0.0, 0.0, 0};
    lcg_ode_roots roots = {1, theta1};
    lcg_cvode_ensemble e = {0};

    for (k = 0; k < NT; ++k)
        tout[k] = 0.5 * k;
    for (i = 0; i < M; ++i) {
        for (k = 0; k < PREFIXU_NY; ++k)
            y0[i * PREFIXU_NY + k] = k == 0 ? 0.05 + 0.02 * i : 0.0;
        for (k = 0; k < PREFIXU_NP; ++k)
            p[i * PREFIXU_NP + k] = PARAMS[k];
        flag[i] = -82;
    }
    for (k = 0; k < M * MAXEV; ++k) {
        ev_t[k] = -1.0;
        ev_which[k] = ev_dir[k] = 7;
    }
    e.model = &PREFIX_model; e.nmem = M; e.nthreads = 3; e.p = p; e.p_stride = PREFIXU_NP; e.y0 = y0;
    e.y0_stride = PREFIXU_NY; e.nt = NT; e.tout = tout; e.final = final; e.flag = flag; e.nt_done = nt_done;
    e.t_reached = t_reached; e.counts = counts; e.roots = &roots; e.rootdir = rootdir; e.terminal = terminal;
    e.max_events = MAXEV; e.ev_t = ev_t; e.ev_y = ev_y; e.ev_which = ev_which; e.ev_direction = ev_dir;
    if (lcg_cvode_solve_many(&e, &opt) != 0)
        return 2;
    for (i = 0; i < M; ++i) {
        long n = counts[i * 8 + 6], kept = n < MAXEV ? n : MAXEV;
        bad += flag[i] != 0 || n < 1;
        dropping += n > MAXEV;
        for (k = 0; k < MAXEV; ++k) {
            long j = (long)i * MAXEV + k;
            if (k < kept)  /* a crossing of theta1 = 0: in the run, theta1 there ~ 0, alternating directions */
                bad += !(ev_t[j] > 0.0 && ev_t[j] <= 5.0) || fabs(ev_y[j * PREFIXU_NY]) > 1e-8 || ev_which[j] != 0
                       || ev_dir[j] != (k % 2 == 0 ? -1 : 1) || (k > 0 && !(ev_t[j] > ev_t[j - 1]));
            else  /* slots past those kept: untouched */
                bad += ev_t[j] != -1.0 || ev_which[j] != 7 || ev_dir[j] != 7;
        }
    }
    printf("bad=%d dropping=%d\n", bad, dropping);
    return bad != 0 || dropping == 0;
}
"""


def test_pool_records_events_strict_and_clean_under_sanitizers(tmp_path, cc):
    """The CVODE pool driver's per-member event arrays filled from C (24 members on 3 threads,
    at most 2 kept each): each kept event a crossing of theta1 = 0 in time order with
    alternating directions, the slots past those kept untouched, members with more events than
    kept counting them all; under AddressSanitizer and UBSan, and the driver strict C99."""
    code = lcg.generate_c(lcg.Scene(lcg.derive(lcg.systems.double_pendulum()), outputs=["energy"]))
    run_cvode_main_sanitized(tmp_path, cc, code, EVENTS_MAIN)


def test_event_arrays_too_large_are_refused_by_name(pend):
    """Members x max_events that cannot be held: a clear error naming max_events, before any run."""
    q0 = np.full((100_000, 1), 0.1)  # x 2e9 events x 4 values: 6.4e15 bytes, more than any machine's memory
    with pytest.raises(lcg.LagcodegenError, match="100000 members x max_events=2000000000 .* do not fit in memory"):
        pend.ensemble([0, 1], q0=q0, events=EVENTS, max_events=2_000_000_000)
