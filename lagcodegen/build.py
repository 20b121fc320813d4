"""Compile generated code into an importable cffi module, cached by content hash.

The cache key covers the sources, the compiler (path and version), the flags, the
lagcodegen version and the SUNDIALS libraries linked. A build runs in a private temporary
folder that is renamed into the cache when complete, so a cached module is never seen half
written, and two processes building the same model at once both succeed (the second
rename loses the race and that process uses the winner's files).

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
"""

from __future__ import annotations

import atexit
import contextlib
import errno
import functools
import io
import hashlib
import importlib.machinery
import importlib.util
import os
import re
import shutil
import stat
import subprocess
import sys
import sysconfig
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import cffi

from .codegen.cffi_decl import model_cdef
from .codegen.record import GeneratedCode
from .codegen.templates import environment
from .errors import CompileError, LagcodegenError
from .version import __version__

DEFAULT_CFLAGS = ("-O2", "-fPIC", "-std=c99")
DEFAULT_FFLAGS = ("-O2", "-fPIC", "-std=f2008", "-ffp-contract=off")  # no FMA: same numbers as C


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


@dataclass(frozen=True)
class Sundials:
    """The SUNDIALS shared libraries bundled in the scikit-sundae wheel."""

    libdir: Path
    libs: dict  # short name ("cvode", "ida", "core") -> file name
    sunindextype: str
    version: str

    def link_args(self, names=("cvode", "core")) -> list[str]:
        missing = [n for n in names if n not in self.libs]
        if missing:
            raise LagcodegenError(f"SUNDIALS libraries {', '.join(missing)} not found in {self.libdir}")
        args = [f"-L{self.libdir}"]
        args += [f"-l:{self.libs[n]}" for n in dict.fromkeys(names)]
        args += [f"-Wl,-rpath,{self.libdir}"]
        return args


@functools.lru_cache(maxsize=1)
def find_sundials() -> Sundials:
    """Locate the SUNDIALS libraries of the installed scikit-sundae wheel."""
    try:
        import sksundae
    except ImportError as exc:  # pragma: no cover - dependency
        raise LagcodegenError("scikit-sundae is not installed: pip install scikit-sundae") from exc
    pkg = Path(sksundae.__file__).resolve().parent
    libdir = pkg.parent / "scikit_sundae.libs"
    libs = {}
    for short in ("cvode", "ida", "core"):
        found = sorted(libdir.glob(f"libsundials_{short}-*.so*")) if libdir.is_dir() else []
        if found:
            libs[short] = found[0].name
    if "cvode" not in libs or "core" not in libs:
        raise LagcodegenError(f"SUNDIALS libraries not found in {libdir}: the native backend needs the "
                              "scikit-sundae wheel's bundled libraries")
    index = "int"
    cfg = pkg / "c_config.pxi"
    if cfg.is_file():
        m = re.search(r"ctypedef\s+([\w ]+?)\s+sunindextype", cfg.read_text())
        if m:
            index = {"int": "int", "long": "long", "long long": "long long",
                     "int64_t": "long long", "int32_t": "int"}.get(m.group(1).strip(), "int")
    ver = re.search(r"\.so\.(\d+\.\d+\.\d+)$", libs["cvode"])
    return Sundials(libdir, libs, index, ver.group(1) if ver else "7")


@functools.lru_cache(maxsize=4)
def compiler_id(cc: str) -> str:
    """Compiler path and version text, part of the cache key."""
    path = shutil.which(cc) or cc
    try:
        ver = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=30).stdout
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise CompileError(f"C compiler {cc!r} cannot be run", [cc, "--version"], str(exc)) from None
    return f"{path}\n{ver}"


def driver_sources(code: GeneratedCode, sundials: Sundials) -> dict[str, str]:
    """The native CVODE driver files of ``code`` (header, source, SUNDIALS declarations)."""
    env = environment()
    ctx = dict(prefix=code.prefix, PREFIX=code.prefix.upper(), version=__version__,
               jacobian=code.jacobian, outputs=bool(code.nout), sparse=bool(getattr(code, "sparse_jacobian", False)),
               sunindextype=sundials.sunindextype, sundials_version=sundials.version)
    return {
        "sundials_api.h": env.get_template("c/sundials_api.h.j2").render(**ctx),
        f"{code.prefix}_cvode.h": env.get_template("c/cvode_driver.h.j2").render(**ctx),
        f"{code.prefix}_cvode.c": env.get_template("c/cvode_driver.c.j2").render(**ctx),
    }


@dataclass(frozen=True)
class BuiltModule:
    """A compiled, loaded cffi module: the code it was built from, where it lives, whether it
    came from the cache. :class:`lagcodegen.solvers.compiled.CompiledModel` wraps it."""

    code: GeneratedCode
    module: object
    path: Path
    native: bool
    cached: bool


def _import(name: str, path: Path):
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


def _load(name: str, final: Path, sofile: Path):
    """The module of the cache entry ``final`` if it is trusted, intact and imports; else None
    (after a one-line warning), the entry removed if it is the user's own."""
    if name in sys.modules:
        return sys.modules[name]
    problem, foreign = _entry_problem(final, sofile)
    if problem is None:
        try:
            return _import(name, sofile)
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


def _run(cmd: list[str], cwd: Path, what: str, code: GeneratedCode) -> None:
    try:
        proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=1800)
    except OSError as exc:
        raise CompileError(f"cannot run the {what} {cmd[0]!r}", cmd, str(exc)) from None
    if proc.returncode != 0:
        raise CompileError(f"compiling model {code.model_name!r} failed ({what}, exit {proc.returncode})",
                           cmd, proc.stdout + proc.stderr)


def build(code: GeneratedCode, native: bool = True, cc: str | None = None,
          cflags: tuple[str, ...] = DEFAULT_CFLAGS, verbose: bool = False,
          fc: str | None = None, fflags: tuple[str, ...] = DEFAULT_FFLAGS) -> BuiltModule:
    """Compile ``code`` (and the native CVODE driver) into a cffi module; cached by content hash.

    Every ``.c`` file of ``code.files`` is compiled with ``cc``, every ``.f90`` file with ``fc``
    (gfortran; its objects are linked in). ``code.cdef_extra`` adds declarations to the cffi
    interface, ``code.cffi_headers`` the headers the module includes, ``code.sundials_libs``
    the SUNDIALS libraries linked besides CVODE (e.g. "ida").
    """
    cc = cc or os.environ.get("CC") or "cc"
    fc = fc or os.environ.get("FC") or "gfortran"
    sundials = find_sundials() if native else None
    sources = dict(code.files)
    headers = [code.header_name, *code.cffi_headers]
    if native:
        sources.update(driver_sources(code, sundials))
        headers.append(f"{code.prefix}_cvode.h")
    fortran = sorted(name for name in sources if name.endswith(".f90"))
    cdef = model_cdef(code, native) + "\n" + code.cdef_extra
    link = sundials.link_args(("cvode", *code.sundials_libs, "core")) if native else []
    ext = importlib.machinery.EXTENSION_SUFFIXES[0]
    h = hashlib.sha256()
    parts = [__version__, f"cache format {CACHE_FORMAT}", compiler_id(cc), " ".join(cflags), " ".join(link),
             ext, cdef, sys.version, *headers, *sorted(f"{k}\0{v}" for k, v in sources.items())]
    if fortran:
        parts += [compiler_id(fc), " ".join(fflags)]
    for part in parts:
        h.update(part.encode())
        h.update(b"\0")
    key = h.hexdigest()[:24]
    modname = f"_lcg_{code.prefix}_{key}"
    root = cache_dir()
    final = root / key
    sofile = final / f"{modname}{ext}"
    if os.path.lexists(final):
        module = _load(modname, final, sofile)
        if module is not None:
            return BuiltModule(code, module, sofile, native, cached=True)
        if os.path.lexists(final):  # not ours to replace: build where only we write
            root = _private_root()
            final = root / key
            sofile = final / f"{modname}{ext}"
    clean_stale(root)
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".build-{key}-{os.getpid()}-", dir=root))
    except OSError as exc:
        raise LagcodegenError(f"cannot write to the build cache {root}: {exc.strerror or exc}; {_HINT}") from None
    try:
        for name, text in sources.items():
            (tmp / name).write_text(text)
        ffi = cffi.FFI()
        ffi.cdef(cdef)
        ffi.set_source(modname, "".join(f'#include "{h}"\n' for h in headers))
        with contextlib.redirect_stdout(io.StringIO()):  # cffi announces the file it writes
            ffi.emit_c_code(str(tmp / f"{modname}.c"))
        if verbose:
            print("lagcodegen: compiling", code.prefix, "...", file=sys.stderr, flush=True)
        objects = []
        for name in fortran:  # modules first: sorted names put dependencies in the caller's hands
            obj = name[:-4] + ".o"
            _run([fc, *fflags, "-c", name, "-o", obj], tmp, "Fortran compiler", code)
            objects.append(obj)
        c_files = [f"{modname}.c"] + sorted(n for n in sources if n.endswith(".c"))
        # No -I on the build folder: the generated files include each other with quotes (found
        # beside the includer), so a model named math, stdlib or Python never shadows <math.h>.
        cmd = [cc, *cflags, "-shared", f"-I{sysconfig.get_paths()['include']}",
               *c_files, *objects, "-o", f"{modname}{ext}", *link, "-lm"]
        if fortran:
            cmd.append("-lgfortran")
        _run(cmd, tmp, "C compiler", code)
        built = tmp / f"{modname}{ext}"
        try:  # never publish a module that does not import
            module = _import(modname, built)
        except Exception as exc:  # noqa: BLE001 - whatever the import raised
            raise LagcodegenError(f"the module compiled for model {code.model_name!r} does not import: "
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
    return BuiltModule(code, module, sofile, native, cached=False)
