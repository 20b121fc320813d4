"""Small shared helpers under the whole pipeline: input checks, bounded excerpts of inputs for
messages, and atomic file writes (with SIGTERM turned into an exception so that they clean up).

Every stage may import this module; it imports nothing of lagcodegen except the errors.
"""

from __future__ import annotations

import contextlib
import math
import operator
import os
import signal
import stat
import tempfile
import threading
import unicodedata
from pathlib import Path
from collections.abc import Mapping

import numpy as np

from .errors import LagcodegenError, ModelError


#: Characters of an offending input an error message shows (see :func:`excerpt`).
EXCERPT = 80


def excerpt(value, around: str | None = None, limit: int = EXCERPT, quote: bool = True) -> str:
    """``repr(value)`` for an error message, bounded: a value whose text is longer than ``limit``
    characters is shown as a quoted excerpt of ``limit`` characters (about ``around`` if it occurs
    in it), ``...`` where cut, and its length, e.g. ``'x*zeta0 + x*ze'... (757 characters)``.
    ``quote=False``: a string as it is, not its repr (text that is part of the message)."""
    try:
        text = value if isinstance(value, str) else repr(value)
    except ValueError:  # the repr of an integer beyond Python's digit limit (sys.set_int_max_str_digits)
        return f"<{type(value).__name__} too large to print>"
    quoted = quote and isinstance(value, str)
    if len(text) <= limit:
        return repr(value) if quoted or not isinstance(value, str) else value
    start = 0
    if around and around in text:
        start = max(0, min(text.index(around) - (limit - len(around)) // 2, len(text) - limit))
    piece = text[start:start + limit]
    shown = repr(piece) if quoted else piece
    return f"{'...' if start else ''}{shown}{'...' if start + limit < len(text) else ''} ({len(text)} characters)"


def lookalike(name: str) -> str | None:
    """If Python reads the name ``name`` as another (its identifiers are NFKC-normalized: the
    full-width ``\uff4b`` is ``k``, ``\u2113`` is ``l``), a description of the first character it
    changes and what it reads as, e.g. ``'\uff4b' (U+FF4B FULLWIDTH LATIN SMALL LETTER K), read as 'k'``;
    else None."""
    if not isinstance(name, str) or unicodedata.normalize("NFKC", name) == name:
        return None
    for ch in name:
        plain = unicodedata.normalize("NFKC", ch)
        if plain != ch:
            return f"{ch!r} (U+{ord(ch):04X} {unicodedata.name(ch, 'unnamed character')}), read as {plain!r}"
    return f"{excerpt(name)} (combining characters), read as {excerpt(unicodedata.normalize('NFKC', name))}"


def check_finite(value, what: str) -> float:
    """Return ``value`` as a float, or raise ModelError if it is not a finite real number."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"{what} must be a real number, got {excerpt(value)}") from None
    if not math.isfinite(x):
        raise ModelError(f"{what} must be finite, got {x}")
    return x


#: ``baumgarte`` of the index-1 formulation that picks (alpha, beta) per run: both equal to the
#: rate of the system's fastest motion at the initial state (``<prefix>_natural_rate``).
BAUMGARTE_AUTO = "auto"


def check_baumgarte(value, what: str = "baumgarte"):
    """``"auto"``, or ``value`` as (alpha, beta), two finite floats; else ModelError."""
    if isinstance(value, str):
        if value == BAUMGARTE_AUTO:
            return BAUMGARTE_AUTO
        raise ModelError(f"{what} must be 'auto' or (alpha, beta), got {excerpt(value)}")
    try:
        alpha, beta = value
    except (TypeError, ValueError):
        raise ModelError(f"{what} must be 'auto' or (alpha, beta), got {excerpt(value)}") from None
    return check_finite(alpha, f"{what} alpha"), check_finite(beta, f"{what} beta")


class FileProblem(LagcodegenError):
    """A file :func:`read_bounded` would not read: ``kind`` "unreadable" (``detail``: the system's
    reason), "not regular" (``detail``: what it is, e.g. "a FIFO") or "too large" (``detail``: its
    size, e.g. "123 bytes" or "more than 100 bytes"). Callers word the message."""

    def __init__(self, kind: str, detail: str):
        super().__init__(f"{kind}: {detail}")
        self.kind, self.detail = kind, detail


def file_kind(mode: int) -> str:
    """What a file of ``st_mode`` ``mode`` is, when it is not a regular file ("a FIFO", ...)."""
    for test, what in ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"), (stat.S_ISLNK, "a link")):
        if test(mode):
            return what
    return "not a regular file"


def read_bounded(path: str | os.PathLike, *, max_bytes: int | None = None, follow_links: bool = True) -> bytes:
    """The bytes of the regular file at ``path``: opened without blocking (a FIFO, a device or a
    folder is refused, never read; with ``follow_links`` False a symbolic link too), at most
    ``max_bytes`` (its size checked first, then never more than ``max_bytes + 1`` bytes read, in
    chunks: a file growing meanwhile is refused too). :class:`FileProblem` saying why not."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    if not follow_links:
        flags |= getattr(os, "O_NOFOLLOW", 0)
        if os.path.islink(path):
            raise FileProblem("not regular", "a link")
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise FileProblem("unreadable", str(exc.strerror or exc)) from None
    mode = os.fstat(fd)
    if not stat.S_ISREG(mode.st_mode):  # checked before a file object is made (a folder's would fail)
        os.close(fd)
        raise FileProblem("not regular", file_kind(mode.st_mode))
    with os.fdopen(fd, "rb") as fh:
        if max_bytes is not None and mode.st_size > max_bytes:
            raise FileProblem("too large", f"{mode.st_size} bytes")
        chunks, size = [], 0
        try:
            while max_bytes is None or size <= max_bytes:
                chunk = fh.read(1 << 20 if max_bytes is None else min(1 << 20, max_bytes + 1 - size))
                if not chunk:
                    break
                chunks.append(chunk)
                size += len(chunk)
        except OSError as exc:
            raise FileProblem("unreadable", str(exc.strerror or exc)) from None
    if max_bytes is not None and size > max_bytes:
        raise FileProblem("too large", f"more than {max_bytes} bytes")
    return b"".join(chunks)


def read_regular_file(path: str | os.PathLike) -> bytes | None:
    """The bytes of ``path`` if it is a regular file (a symbolic link is not followed; a FIFO,
    device or folder is never opened for reading, so nothing blocks), else None
    (:func:`read_bounded`)."""
    try:
        return read_bounded(path, follow_links=False)
    except FileProblem:
        return None


def atomic_write(path: Path, text: str) -> Path:
    """Write ``text`` (UTF-8, newlines as they are) to ``path`` so that readers see the old file
    or the new one, never half (:func:`atomic_binary`)."""
    with atomic_binary(path) as fh:
        fh.write(text.encode("utf-8"))
    return Path(path)


@contextlib.contextmanager
def atomic_binary(path: Path):
    """A binary file object whose contents replace ``path`` when the ``with`` block ends without
    error: a unique temporary file beside ``path`` (created exclusively, so that nothing planted
    there is followed), removed on failure."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            yield fh
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


@contextlib.contextmanager
def staged_outputs(paths):
    """Write several files so that they appear together or not at all: yields a dict mapping
    each of ``paths`` to a unique temporary path beside it with its suffix (writers pick the format
    by it); when the ``with`` block ends without error each temporary file replaces its target.
    On any exception (Ctrl-C, SIGTERM as :class:`Terminated`, a failed writer) the temporary files
    are removed, and so are the folders made here for them (if left empty): nothing is written.

    ``paths``: the files (str or path-like), each given once, None entries skipped."""
    targets = [Path(p) for p in paths if p is not None]
    if len(set(map(os.path.abspath, targets))) != len(targets):
        raise LagcodegenError("the output files must differ: " + ", ".join(map(str, targets)))
    made: list[Path] = []  # folders made here, outermost first
    staged: dict[Path, Path] = {}
    published: list[Path] = []
    try:
        for target in targets:
            missing = []
            parent = target.parent
            while not parent.exists():
                missing.append(parent)
                parent = parent.parent
            target.parent.mkdir(parents=True, exist_ok=True)
            made.extend(reversed(missing))
            fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=f".part{target.suffix}")
            os.close(fd)
            staged[target] = Path(tmp)
        yield dict(staged)
        for target, tmp in staged.items():
            os.chmod(tmp, 0o644)  # mkstemp made it private; an output is a plain file as open() would make it
            os.replace(tmp, target)
            published.append(target)
    except BaseException:
        for target, tmp in staged.items():
            for path in (tmp, target) if target in published else (tmp,):
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(path)
        for folder in reversed(made):
            with contextlib.suppress(OSError):
                folder.rmdir()  # only if empty
        raise


class Terminated(BaseException):
    """SIGTERM as an exception (see :func:`sigterm_raises`); a BaseException, as KeyboardInterrupt,
    so that nothing catches it by accident."""


def _raise_terminated(signum, frame):
    raise Terminated()


@contextlib.contextmanager
def sigterm_raises():
    """Within the block, SIGTERM raises :class:`Terminated` (in the main thread; elsewhere signal
    handlers cannot be set and this does nothing), so that :func:`atomic_write` and
    :func:`atomic_binary` remove their temporary files on the way out."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


_FLOAT64 = np.dtype(np.float64)


def output_times(t) -> np.ndarray:
    """Output times as an array: a numpy array of times as it is; a list or tuple (t0, t1) of
    two numbers gives 1001 evenly spaced output times, a longer one its own times.

    Cheap on the common input (a contiguous float64 array): one comparison pass; strictly
    increasing with finite ends implies every time finite (NaN never compares greater)."""
    pair = isinstance(t, (list, tuple)) and len(t) == 2
    if type(t) is not np.ndarray or t.dtype is not _FLOAT64 or t.ndim != 1 or not t.flags.c_contiguous:
        try:
            t = np.ascontiguousarray(t, dtype=float).ravel()
        except (TypeError, ValueError):
            raise LagcodegenError(f"t must be an array of times, got {t!r:.60}") from None
    if pair:
        t = np.linspace(t[0], t[1], 1001)
    if t.size == 2:  # [t0, t1]
        a, b = t.tolist()
        ok = a < b and math.isfinite(a) and math.isfinite(b)
    elif t.size <= 64:  # a Python pass is cheaper than numpy's on a few values
        times = t.tolist()
        ok = len(times) >= 2 and math.isfinite(times[0]) and math.isfinite(times[-1]) \
            and all(map(operator.lt, times, times[1:]))
    else:
        ok = math.isfinite(t[0]) and math.isfinite(t[-1]) and bool((t[1:] > t[:-1]).all())
    if not ok:
        raise LagcodegenError("t must be at least two finite, strictly increasing times")
    return t


def output_problem(output, plot, written: str) -> str | None:
    """What is wrong with a command's result file ``output`` (.csv or .npz, not a folder) and
    ``plot`` file (.png, or None), in the words "-o FILE: <written> written as .csv or .npz";
    None when both are fine."""
    out = Path(output)
    if out.suffix not in (".csv", ".npz"):
        return f"-o {output}: {written} written as .csv or .npz"
    if out.is_dir():
        return f"-o {output}: is a folder; give a file name ending in .csv or .npz"
    if plot is not None and Path(plot).suffix != ".png":
        return f"--plot {plot}: plots are written as .png"
    for option, name in (("-o", output), ("--plot", plot)):
        problem = None if name is None else folder_problem(Path(name).parent)
        if problem:
            return f"{option} {name}: {problem}"
    return None


def folder_problem(folder: str | os.PathLike) -> str | None:
    """What keeps ``folder`` from being (made) a folder: it, or a folder above it, is an existing
    file that is not a folder ("<that path> is a file, not a folder"); None when it can be made."""
    path = Path(folder)
    for part in (path, *path.parents):
        if part.exists() or part.is_symlink():
            if part.is_dir():
                return None
            return f"{part} is a file, not a folder"
    return None


def fmu_path_problem(path: str | os.PathLike) -> str | None:
    """What is wrong with ``path`` as the FMU file to write: an existing folder (the name of the
    file is asked for, ending in .fmu), or a file where a folder above it should be; None when
    it can be written."""
    path = Path(path)
    if path.is_dir():
        return f"{path} is a folder; give the FMU's file name, ending in .fmu (e.g. {path / 'model.fmu'})"
    return folder_problem(path.parent)


def state_values(val, names: list[str], what: str) -> list[float]:
    """Values for ``names`` from None (zeros), a mapping by name (missing: 0) or a sequence, as
    a list of finite floats; ModelError names what is wrong (unknown names, length, values)."""
    if val is None:
        return [0.0] * len(names)
    if type(val) is list or type(val) is tuple:  # the common case: no abstract-class check
        if len(val) == len(names):
            try:
                out = [float(x) for x in val]
            except (TypeError, ValueError):
                raise ModelError(f"{what} must be numbers, got {val!r:.60}") from None
            if not all(map(math.isfinite, out)):
                raise ModelError(f"{what} has non-finite values")
            return out
    if isinstance(val, Mapping):
        unknown = set(val) - set(names)
        if unknown:
            raise ModelError(f"{what}: unknown coordinate(s) {', '.join(sorted(unknown))}")
        out = [val.get(k, 0.0) for k in names]
    else:
        if isinstance(val, (str, bytes)):
            raise ModelError(f"{what} must be numbers, got {val!r:.60}")
        if not isinstance(val, (list, tuple)):
            try:
                val = np.asarray(val, dtype=float).ravel().tolist()
            except (TypeError, ValueError):
                raise ModelError(f"{what} must be numbers, got {val!r:.60}") from None
        out = val
        if len(out) != len(names):
            raise ModelError(f"{what} has {len(out)} values, expected {len(names)} ({', '.join(names)})")
    try:
        out = [float(x) for x in out]
    except (TypeError, ValueError):
        raise ModelError(f"{what} must be numbers, got {val!r:.60}") from None
    for x in out:
        if not math.isfinite(x):
            raise ModelError(f"{what} has non-finite values")
    return out


def state_vector(val, names: list[str], what: str) -> np.ndarray:
    """:func:`state_values` as an array."""
    return np.array(state_values(val, names, what), dtype=float)


def c_vector(value, size: int, what: str, names=None) -> np.ndarray:
    """``value`` as a contiguous float64 array of exactly ``size`` finite-or-not doubles, ready
    to hand to C; anything else (None, wrong length, non-numeric, complex) raises
    LagcodegenError naming ``what``, the expected length and the ``names`` of the entries.
    Integer arrays are converted, never reinterpreted."""
    if (type(value) is np.ndarray and value.dtype == np.float64 and value.ndim == 1 and value.size == size
            and value.flags.c_contiguous):
        return value
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        arr = None
    if arr is None or value is None or np.iscomplexobj(value):
        raise LagcodegenError(f"{what} must be an array of {size} real numbers"
                              + (f" ({', '.join(names)})" if names else "") + f", got {value!r:.80}")
    arr = np.ascontiguousarray(arr).ravel()
    if arr.size != size:
        raise LagcodegenError(f"{what} has {arr.size} values, expected {size}"
                              + (f" ({', '.join(names)})" if names else ""))
    return arr
