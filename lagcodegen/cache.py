"""The build cache: where compiled modules live, which entries are trusted, how a build is
published (one job: the rules of trust and the atomic publish; :mod:`lagcodegen.build` compiles).

A cached module is code that gets executed, so the cache trusts only what it can check:

* the cache root (``$LAGCODEGEN_CACHE``, else ``~/.cache/lagcodegen``) is created 0700 and used
  only if it is owned by the current user and not group/world-writable; otherwise a one-line
  :class:`CacheWarning` says so and the build goes to a private temporary folder instead;
* an entry is loaded only if its folder and files are the user's own, not group/world-writable,
  and the module's sha256 matches the digest recorded when it was published (checked before
  the module is opened: a truncated or altered module is never loaded). A foreign entry is
  left alone and the model is built privately; a damaged one of the user's own is replaced
  (both with a one-line warning);
* a module is published only after it was imported from its build folder; one that does not
  import is an error, never a cache entry;
* generated files never shadow a system header: the build compiles without ``-I`` on its own
  folder, so ``#include <math.h>`` finds the system's even for a model named ``math``;
* ``.build-*`` folders left by a killed build are removed once stale (owned by the user, and
  their process gone or they are older than any compile).

The pipeline cache (:func:`cached_code`, keys by :func:`pipeline_key`) keeps a model's generated
code under a key of its description (a URDF's bytes, a Model's canonical form, a model file's
model and settings), the compile options and the generator record, in entries of the same kind:
a new process loads the code and its compiled library without deriving or generating anything.
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import errno
import hashlib
import importlib.util
import os
import pickle
import re
import shutil
import stat
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any, Callable

from . import progress as _progress
from .errors import LagcodegenError

#: Layout of a cache entry (part of the key): 2 = the module plus its sha256 in DIGEST_NAME.
#: Layout of a cache entry (part of the key): 2 = the module plus its sha256 in DIGEST_NAME.
CACHE_FORMAT = 2
DIGEST_NAME = "module.sha256"
#: A ``.build-*`` folder of ours whose process is gone is stale after this many seconds; any
#: of ours is after ABANDONED_BUILD_SECONDS (longer than a compile may take, see _run).
STALE_BUILD_SECONDS = 10 * 60
ABANDONED_BUILD_SECONDS = 2 * 3600
_HINT = "set LAGCODEGEN_CACHE to a folder of your own"


class CacheWarning(UserWarning):
    """A cache folder or entry was not used (not the user's own, writable by others, damaged)."""


def _warn(message: str) -> None:
    warnings.warn(message, CacheWarning, stacklevel=3)


def _distrust(st: os.stat_result) -> str | None:
    """Why a cache file or folder with status ``st`` cannot be trusted, or None."""
    uid = os.geteuid()
    if stat.S_ISLNK(st.st_mode):
        return "a symbolic link"
    if st.st_uid != uid:
        return f"owned by uid {st.st_uid}, not by you (uid {uid})"
    if st.st_mode & 0o022:
        who = " and ".join(w for bit, w in ((0o020, "group"), (0o002, "others")) if st.st_mode & bit)
        return f"writable by {who} (mode {stat.S_IMODE(st.st_mode):04o})"
    return None


def _make_root(root: Path) -> None:
    """Create ``root`` (and missing parents) private to the user: 0700 whatever the umask."""
    if root.is_dir():
        return
    missing = []
    p = root
    while not p.exists() and p != p.parent:
        missing.append(p)
        p = p.parent
    for p in reversed(missing):
        try:
            os.mkdir(p, 0o700)
        except FileExistsError:
            continue
        if p == root:
            os.chmod(p, 0o700)


_PRIVATE: list[Path] = []


def _private_root() -> Path:
    """A cache folder for this process only (removed at exit), for builds the cache cannot take."""
    if not _PRIVATE or not _PRIVATE[0].is_dir():
        try:
            path = Path(tempfile.mkdtemp(prefix="lagcodegen-private-"))
        except OSError as exc:
            raise LagcodegenError(f"cannot create a private build folder in {tempfile.gettempdir()}: "
                                  f"{exc.strerror}; {_HINT}") from None
        atexit.register(shutil.rmtree, path, True)
        _PRIVATE[:] = [path]
    return _PRIVATE[0]


def cache_dir() -> Path:
    """Cache root: $LAGCODEGEN_CACHE, else $XDG_CACHE_HOME/lagcodegen or ~/.cache/lagcodegen,
    created 0700. A root not owned by the user, or writable by group or others, is not used
    (a :class:`CacheWarning`): this process then builds in a private folder of its own."""
    root = Path(os.environ.get("LAGCODEGEN_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "lagcodegen"))
    try:
        _make_root(root)
        st = os.stat(root)
    except OSError as exc:
        raise LagcodegenError(f"cannot create the build cache folder {root}: {exc.strerror or exc}; "
                              f"{_HINT}") from None
    if not stat.S_ISDIR(st.st_mode):
        raise LagcodegenError(f"the build cache {root} is not a folder; {_HINT}")
    problem = _distrust(st)
    if problem:
        _warn(f"lagcodegen: build cache {root} is {problem}: not used, building in a private folder "
              f"(chmod go-w it if it is yours, or {_HINT})")
        return _private_root()
    return root



def import_module(name: str, path: Path):
    """Import the extension module ``name`` from ``path`` (once per process)."""
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    sys.modules[name] = module
    return module


def _digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _entry_problem(final: Path, sofile: Path) -> tuple[str | None, bool]:
    """(what is wrong with the cache entry ``final``, whether it is foreign): (None, False) when
    the module can be opened. Nothing of the entry is executed here."""
    digest_file = final / DIGEST_NAME
    for path in (final, sofile, digest_file):
        try:
            st = os.lstat(path)
        except FileNotFoundError:
            return f"{path.name} is missing", False
        except OSError as exc:
            return f"{path.name} cannot be read ({exc.strerror})", True
        problem = _distrust(st)
        if problem:
            return f"{path.name if path != final else 'its folder'} is {problem}", st.st_uid != os.geteuid()
        if path != final and not stat.S_ISREG(st.st_mode):
            return f"{path.name} is not a regular file", False
    try:
        recorded = digest_file.read_text().split()[0] if digest_file.stat().st_size < 4096 else ""
        actual = _digest(sofile)
    except (OSError, IndexError, UnicodeDecodeError):
        return "its digest cannot be read", False
    if actual != recorded:
        return "the module does not match its recorded sha256 digest (truncated or altered)", False
    return None, False


_LIBRARIES: dict = {}


def open_library(name: str, path: Path):
    """Open the model library ``name`` at ``path`` (once per process; local symbols, bound now)."""
    lib = _LIBRARIES.get(name)
    if lib is None:
        lib = _LIBRARIES[name] = ctypes.CDLL(str(path), mode=os.RTLD_NOW | os.RTLD_LOCAL)
    return lib


def _load(name: str, final: Path, sofile: Path, opener):
    """What ``opener`` (:func:`import_module`, :func:`open_library`) opens of the cache entry
    ``final`` if it is trusted, intact and opens; else None (after a one-line warning), the
    entry removed if it is the user's own."""
    if name in sys.modules or name in _LIBRARIES:
        return opener(name, sofile)
    problem, foreign = _entry_problem(final, sofile)
    if problem is None:
        try:
            return opener(name, sofile)
        except Exception as exc:  # noqa: BLE001 - any failed import means: rebuild
            problem = f"the module does not import ({type(exc).__name__}: {str(exc)[:200]})"
    if foreign:
        _warn(f"lagcodegen: cache entry {final} not used: {problem}; building a private copy")
    else:
        _warn(f"lagcodegen: cache entry {final} not used: {problem}; rebuilding it")
        _discard(final)
    return None


def _discard(entry: Path) -> None:
    """Remove a cache entry of ours: renamed aside first (one step, so that no other process
    sees it half removed), then deleted."""
    aside = entry.with_name(f".stale-{entry.name}-{os.getpid()}-{os.urandom(4).hex()}")
    try:
        os.rename(entry, aside)
    except OSError:
        return  # gone already (another process), or not ours to move
    if os.path.islink(aside):
        os.unlink(aside)
    else:
        shutil.rmtree(aside, ignore_errors=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


def clean_stale(root: Path, now: float | None = None) -> list[Path]:
    """Remove the ``.build-*`` folders of ``root`` left by killed builds (the user's own only,
    whose process is gone and older than STALE_BUILD_SECONDS, or older than
    ABANDONED_BUILD_SECONDS) and entries set aside for removal; returns what was removed."""
    now = time.time() if now is None else now
    removed = []
    try:
        entries = list(os.scandir(root))
    except OSError:
        return removed
    for entry in entries:
        building, stale = entry.name.startswith(".build-"), entry.name.startswith(".stale-")
        if not (building or stale):
            continue
        try:
            st = entry.stat(follow_symlinks=False)
        except OSError:
            continue
        if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.geteuid():
            continue
        age = now - st.st_mtime
        if building:
            m = re.fullmatch(r"\.build-[0-9a-f]+-(\d+)-.*", entry.name)
            pid = int(m.group(1)) if m else None
            if not (age > ABANDONED_BUILD_SECONDS
                    or (age > STALE_BUILD_SECONDS and pid is not None and not _alive(pid))):
                continue
        shutil.rmtree(entry.path, ignore_errors=True)
        removed.append(Path(entry.path))
    return removed


def _secure(folder: Path) -> None:
    """Take group/world write permission off everything in a build folder (umask 000)."""
    for path in folder.iterdir():
        st = os.lstat(path)
        if stat.S_ISREG(st.st_mode) and st.st_mode & 0o022:
            os.chmod(path, stat.S_IMODE(st.st_mode) & ~0o022)



def cache_key(parts: list[str]) -> str:
    h = hashlib.sha256()
    for part in parts:
        h.update(part.encode())
        h.update(b"\0")
    return h.hexdigest()[:24]


def cached_build(key: str, modname: str, filename: str, make, opener):
    """(what ``opener`` opens, its path, whether it came from the cache) for the cache entry
    ``key``: loaded if present and trusted, else built by ``make(folder)`` (which writes and
    compiles everything into ``folder`` and returns the built file), opened from its build
    folder, then published atomically with its digest."""
    root = cache_dir()
    final = root / key
    sofile = final / filename
    if os.path.lexists(final):
        loaded = _load(modname, final, sofile, opener)
        if loaded is not None:
            return loaded, sofile, True
        if os.path.lexists(final):  # not ours to replace: build where only we write
            root = _private_root()
            final = root / key
            sofile = final / filename
    clean_stale(root)
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".build-{key}-{os.getpid()}-", dir=root))
    except OSError as exc:
        raise LagcodegenError(f"cannot write to the build cache {root}: {exc.strerror or exc}; {_HINT}") from None
    try:
        built = make(tmp)
        try:  # never publish a module that does not import
            loaded = opener(modname, built)
        except Exception as exc:  # noqa: BLE001 - whatever the import raised
            raise LagcodegenError(f"the module compiled as {modname} does not import: "
                                  f"{type(exc).__name__}: {str(exc)[:300]}") from None
        _secure(tmp)
        (tmp / DIGEST_NAME).write_text(f"{_digest(built)}  {built.name}\n")
        _secure(tmp)
        try:
            os.rename(tmp, final)  # atomic publish of the complete folder
        except OSError as exc:
            if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):  # not a lost race
                raise LagcodegenError(f"cannot publish into the build cache {root}: {exc.strerror}; "
                                      f"{_HINT}") from None
        else:
            tmp = None
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return loaded, sofile, False


def pipeline_key(kind: str, *parts: str) -> str:
    """The pipeline cache's key of ``parts`` (a model's description and its options, as text)
    with the generator record (lagcodegen's sources' digest, sympy and symengine)."""
    from .buildstep import generator_record

    return cache_key([kind, *parts, repr(sorted(generator_record().items()))])


def cached_code(key: str, what: str, make: Callable[[], tuple[Any, Any]], build: Callable[[Any, bool], Any]):
    """``build(entry, cached)`` of the pipeline cache's entry ``key``: the pickled record of a
    model's generated code (and whatever else ``make`` records), read back in a new process
    without deriving or generating; on a miss ``make()`` gives (the entry in memory, the record to
    pickle) and a progress stage ``build <what> (not cached)`` covers the whole build, its
    generation and compilation (:mod:`lagcodegen.progress`: a line once it has lasted a second,
    a callback at once; nothing at all on a hit). A damaged entry is rebuilt, never used
    (:func:`lagcodegen.cache.cached_build` checks its digest; one that does not unpickle is
    discarded with a warning)."""
    made: dict = {}
    with contextlib.ExitStack() as stack:
        def produce(folder: Path) -> Path:
            stack.enter_context(_progress.stage("build", unit=f"{what} (not cached)"))
            made["entry"], record = make()
            out = folder / "code.pickle"
            out.write_bytes(pickle.dumps(record, protocol=pickle.HIGHEST_PROTOCOL))
            return out

        def opener(_name: str, file: Path):
            if "entry" in made:  # the entry just built, with its scene
                return made["entry"]
            return pickle.loads(file.read_bytes())  # an entry of the user's own cache, checked by its digest

        entry, _, cached = cached_build(key, f"lcg_code_{key}", "code.pickle", produce, opener)
        return build(entry, cached)
