"""Progress of the long stages (derive, formulate, cse; the build's compiler runs) and Ctrl-C
during long C calls.

A stage reports how far it is::

    with progress.stage("derive", total=n, unit="coordinates") as s:
        for i in range(n):
            ...
            s.advance()

Nothing is reported unless a caller asked for it with :func:`enabled`: ``enabled(True)`` draws
one line on stderr, ``lagcodegen: derive 12/50 coordinates, 3.1 s``, once a stage has lasted
:data:`AFTER` seconds (refreshed in place on a terminal, a new line every :data:`LOG_EVERY`
seconds elsewhere, erased on a terminal when the stage ends); ``enabled(callback)`` calls
``callback(stage, done, total, elapsed)`` when a stage begins, on every :meth:`Stage.advance`
and when it ends (``total`` None when the stage does not know it; an exception raised by the
callback stops the work). Off (the default in Python), :func:`stage` returns one shared object
whose methods do nothing: a few hundred nanoseconds per stage, tens per advance. The line is
redrawn by a small thread, so that a stage without loop points (a compiler run) still shows
its elapsed time; callbacks are always called from the thread doing the work.

Lines drawn by others (the ensembles' members-done bar) go through :class:`StatusLine`, which
keeps the same rule: redrawn in place at most every :data:`REFRESH` seconds on a terminal, one
line every :data:`LOG_EVERY` seconds into a log file or a pipe.

Ctrl-C: Python runs its SIGINT handler only between bytecodes, so one long C call holding the
GIL (symengine's common-subexpression elimination of a 50-link chain: seconds) delays
KeyboardInterrupt until it returns. :func:`isolated` runs such a call in a forked child
process and waits for its pickled result in an interruptible read: Ctrl-C (or SIGTERM through
:func:`lagcodegen.util.sigterm_raises`) then raises at once in the caller and kills the child.

One of the lowest stages (beside :mod:`lagcodegen.util`): imports nothing of lagcodegen but the
errors.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import pickle
import signal
import sys
import threading
import time
import warnings
from typing import Any, Callable

from .errors import LagcodegenError

#: Seconds a stage lasts before its line appears (the callback is called from the start).
AFTER = 1.0
#: Seconds between two redraws of the line on a terminal.
REFRESH = 0.2
#: Seconds between two lines when stderr is not a terminal (a log file, a pipe).
LOG_EVERY = 5.0
#: :func:`isolated` forks only where this is True (POSIX with fork, not macOS, whose system
#: libraries do not survive a fork without exec); elsewhere it calls directly.
FORK = hasattr(os, "fork") and sys.platform != "darwin"

Callback = Callable[[str, int, "int | None", float], Any]


class Stage:
    """One running stage: ``name``, ``done`` of ``total`` (None: unknown) ``unit``. Returned by
    :func:`stage` when progress is enabled; :meth:`advance` may be called from any thread."""

    __slots__ = ("name", "total", "unit", "done", "start", "_reporter", "_lock")

    def __init__(self, reporter, name: str, total: int | None, unit: str):
        self.name, self.total, self.unit = name, total, unit
        self.done = 0
        self.start = time.perf_counter()
        self._reporter = reporter
        self._lock = threading.Lock()

    def advance(self, k: int = 1) -> None:
        """``k`` more units done."""
        with self._lock:
            self.done += k
            done = self.done
        self._reporter.update(self, done)

    def set(self, done: int, total: int | None = None) -> None:
        """``done`` units done (and a new ``total`` if given)."""
        with self._lock:
            self.done = done
            if total is not None:
                self.total = total
        self._reporter.update(self, done)

    def elapsed(self) -> float:
        return time.perf_counter() - self.start

    def text(self) -> str:
        """``derive 12/50 coordinates`` (``cse 1325 expressions`` without a total)."""
        count = f" {self.done}/{self.total}" if self.total is not None else ""
        return f"{self.name}{count}{' ' + self.unit if self.unit else ''}"

    def __enter__(self) -> "Stage":
        self._reporter.enter(self)
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self._reporter.leave(self, exc_type is None)


class _Off:
    """The stage of a disabled reporter: every method does nothing."""

    __slots__ = ()
    name, total, unit, done = "", None, "", 0

    def advance(self, k: int = 1) -> None:
        pass

    def set(self, done: int, total: int | None = None) -> None:
        pass

    def elapsed(self) -> float:
        return 0.0

    def __enter__(self) -> "_Off":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        pass


OFF = _Off()


class _CallbackReporter:
    """Calls ``callback(stage, done, total, elapsed)`` on entry, every advance and exit."""

    def __init__(self, callback: Callback):
        self.callback = callback

    def enter(self, s: Stage) -> None:
        self.callback(s.name, 0, s.total, 0.0)

    def update(self, s: Stage, done: int) -> None:
        self.callback(s.name, done, s.total, s.elapsed())

    def leave(self, s: Stage, ok: bool) -> None:
        if ok:
            self.callback(s.name, s.done, s.total, s.elapsed())


def _is_terminal(stream) -> bool:
    """Whether ``stream`` is a terminal (False for a closed stream or one without ``isatty``)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


class _LineReporter:
    """One line on ``stream`` for the innermost open stages (outer ones named first), with the
    outermost stage's elapsed time; drawn by a thread while a stage is open."""

    def __init__(self, stream=None):
        self.stream = stream if stream is not None else sys.stderr
        self.tty = _is_terminal(self.stream)
        self.open: list[Stage] = []
        self.lock = threading.Lock()
        self.width = 0  # characters of the line on screen (terminal)
        self.last = None  # time of the last draw
        self.stop: threading.Event | None = None
        self.thread: threading.Thread | None = None

    def line(self) -> str:
        stages = list(self.open)
        if not stages:
            return ""
        return f"lagcodegen: {': '.join(s.text() for s in stages)}, {stages[0].elapsed():.1f} s"

    def draw(self, final: bool = False) -> None:
        """Draw the line if it is due (the outermost stage has lasted AFTER seconds, and the
        last draw is REFRESH or LOG_EVERY seconds old) or ``final`` and it was drawn before."""
        with self.lock:
            if not self.open:
                return
            now = time.perf_counter()
            if final:
                if self.last is None:
                    return
            elif now - self.open[0].start < AFTER or (
                    self.last is not None and now - self.last < (REFRESH if self.tty else LOG_EVERY)):
                return
            text = self.line()
            try:
                if self.tty:
                    self.stream.write("\r" + text + " " * max(0, self.width - len(text)))
                    self.width = len(text)
                else:
                    self.stream.write(text + "\n")
                self.stream.flush()
            except (OSError, ValueError):  # a closed stream: drawing is best effort
                pass
            self.last = now

    def erase(self) -> None:
        with self.lock:
            if self.tty and self.width:
                try:
                    self.stream.write("\r" + " " * self.width + "\r")
                    self.stream.flush()
                except (OSError, ValueError):
                    pass
            self.width = 0
            self.last = None

    def enter(self, s: Stage) -> None:
        with self.lock:
            self.open.append(s)
            first = len(self.open) == 1
        if first:
            self.stop = threading.Event()
            self.thread = threading.Thread(target=self._run, args=(self.stop,), name="lagcodegen-progress",
                                           daemon=True)
            self.thread.start()
        self.draw()

    def update(self, s: Stage, done: int) -> None:
        pass  # the thread redraws

    def leave(self, s: Stage, ok: bool) -> None:
        if ok and len(self.open) == 1 and not self.tty:
            self.draw(final=True)
        with self.lock:
            if s in self.open:
                self.open.remove(s)
            last = not self.open
        if last:
            if self.stop is not None:
                self.stop.set()
                if self.thread is not threading.current_thread():
                    self.thread.join()
            self.stop = self.thread = None
            self.erase()

    def _run(self, stop: threading.Event) -> None:
        while not stop.wait(REFRESH):
            self.draw()


class StatusLine:
    """One status line on ``stream`` (default stderr) that a caller redraws as often as it likes:
    on a terminal rewritten in place (``\\r``) at most every :data:`REFRESH` seconds; elsewhere
    (a log file, a pipe) a new line at most every :data:`LOG_EVERY` seconds, never a carriage
    return. :meth:`close` draws the last text (if anything was drawn) and ends the line."""

    def __init__(self, stream=None):
        self.stream = stream if stream is not None else sys.stderr
        self.tty = _is_terminal(self.stream)
        self.last: float | None = None  # time of the last draw
        self.text = ""
        self.drawn = False  # the latest text is on the stream

    def write(self, text: str, force: bool = False) -> bool:
        """Show ``text`` if a draw is due (or ``force``); returns True if it was written."""
        self.text, self.drawn = text, False
        now = time.perf_counter()
        if not force and self.last is not None and now - self.last < (REFRESH if self.tty else LOG_EVERY):
            return False
        try:
            self.stream.write(("\r" + text) if self.tty else (text.rstrip() + "\n"))
            self.stream.flush()
        except (OSError, ValueError):  # a closed stream: drawing is best effort
            return False
        self.last, self.drawn = now, True
        return True

    def close(self) -> None:
        """Draw the latest text if it was not drawn, then end the line (a terminal's newline)."""
        if self.last is None:
            return
        if not self.drawn:
            self.write(self.text, force=True)
        if self.tty:
            try:
                self.stream.write("\n")
                self.stream.flush()
            except (OSError, ValueError):
                pass


_reporter: contextvars.ContextVar = contextvars.ContextVar("lagcodegen_progress", default=None)


@contextlib.contextmanager
def enabled(how: "bool | Callback | None" = True, stream=None):
    """Within the block, stages report: ``True`` a line on ``stream`` (default stderr),
    ``False`` nothing, a callable ``callback(stage, done, total, elapsed)``; ``None`` keeps
    whatever the surrounding code chose. The setting belongs to the current thread (and
    context): threads started inside see progress off."""
    if how is None:
        yield
        return
    if how is True:
        reporter = _LineReporter(stream)
    elif how is False:
        reporter = None
    elif callable(how):
        reporter = _CallbackReporter(how)
    else:
        raise LagcodegenError(f"progress must be True, False, None or a callable "
                              f"(stage, done, total, elapsed), got {how!r:.80}")
    token = _reporter.set(reporter)
    try:
        yield
    finally:
        _reporter.reset(token)


def active() -> bool:
    """True if stages report (a line or a callback) in this context."""
    return _reporter.get() is not None


def stage(name: str, total: int | None = None, unit: str = ""):
    """A context manager for one stage of work, yielding an object with ``advance(k=1)`` and
    ``set(done, total=None)``: a :class:`Stage` if progress is enabled, else :data:`OFF`."""
    reporter = _reporter.get()
    if reporter is None:
        return OFF
    return Stage(reporter, name, total, unit)


# ---------------------------------------------------------------------- Ctrl-C during long C calls
def can_isolate() -> bool:
    """True if :func:`isolated` would fork here: the platform allows it (:data:`FORK`), this is
    the main thread (the only one Python delivers signals to) and SIGINT runs a Python handler
    (with SIG_DFL Ctrl-C ends the process anyway; with SIG_IGN nothing is to be interrupted)."""
    return (FORK and threading.current_thread() is threading.main_thread()
            and callable(signal.getsignal(signal.SIGINT)))


def isolated(fn: Callable, *args: Any) -> Any:
    """``fn(*args)``, computed in a forked child process when :func:`can_isolate` (the result
    comes back pickled, so it must pickle), else directly. Ctrl-C (any signal whose Python
    handler raises) interrupts the wait at once: the child is killed and the exception raised
    here. An exception of ``fn`` is raised here too; a child that dies without an answer (out
    of memory, say) makes the call run in this process."""
    if not can_isolate():
        return fn(*args)
    read_end, write_end = os.pipe()
    pid = -1  # no child yet
    chunks = []
    # Everything from the fork on is inside the try: a Ctrl-C that lands before the wait must kill
    # the child too, or it would run on for hours holding the caller's inherited pipes. Around the
    # fork itself Ctrl-C is held back: the fork hooks run Python code (logging releases its lock in
    # os.register_at_fork's after_in_parent), and an exception raised there is printed and
    # dropped, so the KeyboardInterrupt would be lost; held back, it is raised right after.
    try:
        held = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD_SIGNALS)
        try:
            with warnings.catch_warnings():  # Python >= 3.12 warns about fork() beside other threads
                warnings.simplefilter("ignore", DeprecationWarning)
                pid = os.fork()
        finally:
            if pid != 0:  # the parent (or no fork at all): a held-back Ctrl-C is raised now
                signal.pthread_sigmask(signal.SIG_SETMASK, held)
        if pid == 0:  # pragma: no cover - the child (coverage does not follow it); never returns
            _child(write_end, read_end, fn, args, held)
        os.close(write_end)
        write_end = -1
        while True:
            data = os.read(read_end, 1 << 20)  # a signal handler that raises ends the wait here
            if not data:
                break
            chunks.append(data)
        _, status = os.waitpid(pid, 0)
    except BaseException:
        if pid > 0:
            _kill(pid)
        raise
    finally:
        os.close(read_end)
        if write_end >= 0:
            os.close(write_end)
    if os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGINT:
        raise KeyboardInterrupt  # Ctrl-C reached the child first (one process group)
    try:
        ok, value = pickle.loads(b"".join(chunks))
    except Exception:
        return fn(*args)  # the child died without an answer: compute it here
    if ok:
        return value
    raise value


#: Signals held back while :func:`isolated` forks (their Python handlers raise).
_HELD_SIGNALS = {signal.SIGINT, signal.SIGTERM}


def _child(write_end: int, read_end: int, fn: Callable, args, mask) -> None:  # pragma: no cover - in the child
    """Compute ``fn(*args)`` and write the pickled (ok, value) pair; never returns. ``mask``: the
    signal mask to restore once Ctrl-C and SIGTERM have their default actions here."""
    try:
        os.close(read_end)
        signal.signal(signal.SIGINT, signal.SIG_DFL)  # the parent decides what Ctrl-C means
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        try:
            payload = pickle.dumps((True, fn(*args)), protocol=pickle.HIGHEST_PROTOCOL)
        except BaseException as exc:
            try:
                payload = pickle.dumps((False, exc), protocol=pickle.HIGHEST_PROTOCOL)
            except Exception:
                payload = pickle.dumps((False, LagcodegenError(f"{type(exc).__name__}: {exc}")))
        view = memoryview(payload)
        while view:
            view = view[os.write(write_end, view):]
    finally:
        os._exit(0)


def _kill(pid: int) -> None:
    """End the child ``pid`` and reap it."""
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, signal.SIGKILL)
    with contextlib.suppress(ChildProcessError):
        os.waitpid(pid, 0)
