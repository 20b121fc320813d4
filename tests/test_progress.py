"""Progress of the long stages (lagcodegen.progress) and Ctrl-C during long C calls.

No timing: the tests check which stages report and in what order, what the line says, that a
forked computation gives the same result, and that SIGINT ends a process stuck in a long C call
(exit code, no traceback) instead of waiting for the call to return."""

import io
import os
import signal
import subprocess
import sys
import textwrap
import threading
import uuid
import time
from pathlib import Path

import pytest
import symengine as se

from lagcodegen import progress
from lagcodegen.derivation import derive
from lagcodegen.errors import LagcodegenError
from lagcodegen.formulation import kernels
from lagcodegen.formulation.kernels import model_blocks
from lagcodegen.formulation.scene import Scene
from lagcodegen.model.systems import n_link_pendulum, pendulum

ROOT = Path(__file__).resolve().parents[1]


class Recorder:
    def __init__(self):
        self.calls = []

    def __call__(self, stage, done, total, elapsed):
        self.calls.append((stage, done, total, elapsed))

    def of(self, stage):
        return [c for c in self.calls if c[0] == stage]


class Tty(io.StringIO):
    def isatty(self):
        return True


@pytest.fixture
def immediate(monkeypatch):
    """Lines drawn from a stage's start (no waiting for AFTER seconds)."""
    monkeypatch.setattr(progress, "AFTER", 0.0)


def test_off_by_default_and_cheap():
    assert not progress.active()
    s = progress.stage("derive", total=3)
    assert s is progress.OFF  # one shared object: nothing allocated, nothing reported
    with s as same:
        same.advance()
        same.set(2, 3)
    assert s.done == 0


def test_derive_reports_every_coordinate_to_a_callback():
    rec = Recorder()
    with progress.enabled(rec):
        assert progress.active()
        derive(n_link_pendulum(4))
    calls = rec.of("derive")
    done = [c[1] for c in calls]
    assert done[0] == 0 and done[-1] == 4 and {c[2] for c in calls} == {4}
    assert done == sorted(done) and set(done) == {0, 1, 2, 3, 4}
    elapsed = [c[3] for c in calls]
    assert elapsed == sorted(elapsed)
    assert not progress.active()  # the setting ends with the block


def test_formulate_counts_rows_and_jacobian_columns():
    eom = derive(n_link_pendulum(3))
    rec = Recorder()
    with progress.enabled(rec):
        model_blocks(Scene(eom, jacobian=False))
        model_blocks(Scene(eom, jacobian=True, jacobian_form="expanded"))
    totals = [c[2] for c in rec.of("formulate") if c[1] == 0]
    assert totals == [3, 3 + 6]
    assert max(c[1] for c in rec.of("formulate")) == 9


def test_a_callback_that_raises_stops_the_derivation():
    class Stop(Exception):
        pass

    def cb(stage, done, total, elapsed):
        if stage == "derive" and done == 2:
            raise Stop

    with pytest.raises(Stop), progress.enabled(cb):
        derive(n_link_pendulum(5))


def test_enabled_none_keeps_the_setting_and_bad_values_are_refused():
    rec = Recorder()
    with progress.enabled(rec):
        with progress.enabled(None):
            assert progress.active()
        with progress.enabled(False):
            assert not progress.active()
            derive(pendulum())
    assert rec.calls == []
    with pytest.raises(LagcodegenError, match="progress must be"):
        with progress.enabled("yes"):
            pass


def test_the_setting_belongs_to_the_thread():
    seen = []
    with progress.enabled(Recorder()):
        t = threading.Thread(target=lambda: seen.append(progress.active()))
        t.start()
        t.join()
    assert seen == [False]


def test_a_stage_advanced_from_worker_threads_counts_every_step():
    rec = Recorder()
    with progress.enabled(rec):
        with progress.stage("compile", total=40, unit="files") as s:
            workers = [threading.Thread(target=lambda: [s.advance() for _ in range(10)]) for _ in range(4)]
            for w in workers:
                w.start()
            for w in workers:
                w.join()
    assert rec.calls[-1][:3] == ("compile", 40, 40)


def test_line_in_a_log_names_the_stage_and_how_far(immediate):
    out = io.StringIO()
    with progress.enabled(True, stream=out):
        derive(n_link_pendulum(3))
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("lagcodegen: derive 0/3 coordinates, ")
    assert lines[-1].startswith("lagcodegen: derive 3/3 coordinates, ") and lines[-1].endswith(" s")
    assert "\r" not in out.getvalue()


def test_line_on_a_terminal_is_redrawn_in_place_and_erased(immediate):
    out = Tty()
    with progress.enabled(True, stream=out):
        with progress.stage("generate", total=3, unit="blocks") as s:
            s.advance()
            with progress.stage("cse", unit="of 5 expressions"):
                text = progress._reporter.get().line()
    assert text.startswith("lagcodegen: generate 1/3 blocks: cse of 5 expressions, ")
    value = out.getvalue()
    assert value.startswith("\rlagcodegen: generate 0/3 blocks")
    assert value.endswith("\r") and value.rstrip("\r").split("\r")[-1].strip() == ""  # erased
    assert "\n" not in value


def test_no_line_before_a_stage_has_lasted(monkeypatch):
    monkeypatch.setattr(progress, "AFTER", 3600.0)
    out = io.StringIO()
    with progress.enabled(True, stream=out):
        derive(n_link_pendulum(3))
    assert out.getvalue() == ""


def test_compile_model_takes_a_progress_callback():
    import lagcodegen as lcg
    rec = Recorder()
    prefix = f"progress_{uuid.uuid4().hex[:12]}"  # a model not in the pipeline cache: really built
    sim = lcg.compile_model(pendulum(), progress=rec, prefix=prefix)
    assert {"build", "derive", "formulate"} <= {c[0] for c in rec.calls}
    assert rec.calls[0][0] == "build"  # the stage of a build that really runs, opened first
    rec.calls.clear()
    lcg.compile_model(pendulum(), progress=rec, prefix=prefix)  # from the cache: no stage at all
    assert rec.calls == []
    assert not progress.active()
    res = sim.simulate([0, 1], q0=[0.5])
    assert res.t[-1] == 1.0


@pytest.mark.skipif(not progress.can_isolate(), reason="no fork here")
def test_isolated_runs_in_a_child_and_returns_its_result():
    assert progress.isolated(os.getpid) != os.getpid()
    with pytest.raises(ValueError, match="invalid literal"):
        progress.isolated(int, "x")


def test_isolated_calls_directly_where_it_cannot_fork():
    box = []
    t = threading.Thread(target=lambda: box.append(progress.isolated(os.getpid)))
    t.start()
    t.join()
    assert box == [os.getpid()]


def test_cse_in_a_child_equals_cse_here(monkeypatch):
    exprs = model_blocks(Scene(derive(n_link_pendulum(6)), jacobian=False))["rhs"].exprs
    monkeypatch.setattr(kernels, "ISOLATE_CSE_OPS", float("inf"))
    here = kernels.cse(exprs)
    monkeypatch.setattr(kernels, "ISOLATE_CSE_OPS", 0)
    child = kernels.cse(exprs)
    assert here == se.cse(list(exprs))
    assert [(str(a), str(b)) for a, b in child[0]] == [(str(a), str(b)) for a, b in here[0]]
    assert [str(e) for e in child[1]] == [str(e) for e in here[1]]


def test_cse_cost_counts_operations_and_expressions():
    x, y = se.symbols("x y")
    assert kernels.cse_cost([]) == 0
    assert kernels.cse_cost([x] * 5) == 50
    assert kernels.cse_cost([x * y + x, x]) == 2 + 20


def test_cse_is_a_stage():
    rec = Recorder()
    with progress.enabled(rec):
        kernels.cse([se.Symbol("x") + se.Symbol("y")] * 2)
    assert rec.calls[0][:3] == ("cse", 0, None) and len(rec.of("cse")) == 2


def _children(pid):
    try:
        return [int(p) for p in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except OSError:
        return []


@pytest.mark.skipif(not progress.can_isolate() or not Path(f"/proc/{os.getpid()}/task").is_dir(),
                    reason="needs fork and /proc")
def test_sigint_stops_a_long_c_call_at_once(tmp_path):
    """sum(range(10**13)) holds the GIL for hours in one C call; isolated, SIGINT ends it."""
    script = tmp_path / "stuck.py"
    script.write_text(textwrap.dedent("""
        import sys
        from lagcodegen import progress
        print("ready", flush=True)
        try:
            progress.isolated(sum, range(10**13))
        except KeyboardInterrupt:
            print("interrupted", file=sys.stderr)
            sys.exit(130)
    """))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)
    try:
        assert proc.stdout.readline().strip() == "ready"
        while not _children(proc.pid):  # the forked child exists: the parent waits for it
            assert proc.poll() is None
            time.sleep(0.01)
        child = _children(proc.pid)[0]
        proc.send_signal(signal.SIGINT)
        err = proc.communicate(timeout=60)[1]  # a bound, not a measurement: without the fork, hours
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    assert not Path(f"/proc/{child}").exists()  # killed and reaped


@pytest.mark.skipif(not progress.can_isolate() or not Path(f"/proc/{os.getpid()}/task").is_dir(),
                    reason="needs fork and /proc")
def test_sigint_during_the_fork_hooks_is_not_lost(tmp_path):
    """A Ctrl-C that arrives while fork's Python hooks run (logging's after_in_parent, here one that
    sends the signal itself) would raise inside the hook, where Python prints and drops it; held
    back around the fork it is raised afterwards, the child killed."""
    script = tmp_path / "hooked.py"
    script.write_text(textwrap.dedent("""
        import os, signal, sys
        from lagcodegen import progress
        os.register_at_fork(after_in_parent=lambda: os.kill(os.getpid(), signal.SIGINT))
        try:
            progress.isolated(sum, range(10**13))
        except KeyboardInterrupt:
            print("interrupted", file=sys.stderr)
            sys.exit(130)
    """))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)
    try:
        err = proc.communicate(timeout=60)[1]  # a bound, not a measurement: with the signal lost, hours
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err and "Exception ignored" not in err


def test_sigint_during_a_derivation_exits_130_without_traceback(tmp_path):
    models = tmp_path / "chain.py"
    models.write_text(textwrap.dedent("""
        import sys
        from lagcodegen.model.systems import n_link_pendulum

        def chain():
            print("MODEL READY", file=sys.stderr, flush=True)
            return n_link_pendulum(30)
    """))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = tmp_path / "gen"
    proc = subprocess.Popen([sys.executable, "-m", "lagcodegen", "generate", f"{models}:chain", "-o", str(out),
                             "--no-jacobian", "--no-progress"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)
    try:
        assert proc.stderr.readline().strip() == "MODEL READY"  # the derivation is next
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "lagcodegen: interrupted" in err and "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())
