"""Compile generated code into an importable cffi module, cached by content hash.

The cache key covers the sources, the compiler (path and version), the flags, the
lagcodegen version and the SUNDIALS libraries linked. A build runs in a private temporary
folder that is renamed into the cache when complete, so a cached module is never seen half
written, and two processes building the same model at once both succeed (the second
rename loses the race and that process uses the winner's files).
"""

from __future__ import annotations

import contextlib
import functools
import io
import hashlib
import importlib.machinery
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
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


def cache_dir() -> Path:
    """Cache root: $LAGCODEGEN_CACHE, else ~/.cache/lagcodegen."""
    root = os.environ.get("LAGCODEGEN_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "lagcodegen")
    path = Path(root)
    path.mkdir(parents=True, exist_ok=True)
    return path


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


def _load(name: str, path: Path):
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    sys.modules[name] = module
    return module


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
    parts = [__version__, compiler_id(cc), " ".join(cflags), " ".join(link), ext, cdef, sys.version,
             *headers, *sorted(f"{k}\0{v}" for k, v in sources.items())]
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
    if sofile.is_file():
        return BuiltModule(code, _load(modname, sofile), sofile, native, cached=True)

    tmp = Path(tempfile.mkdtemp(prefix=f".build-{key}-", dir=root))
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
        cmd = [cc, *cflags, "-shared", f"-I{tmp}", f"-I{sysconfig.get_paths()['include']}",
               *c_files, *objects, "-o", f"{modname}{ext}", *link, "-lm"]
        if fortran:
            cmd.append("-lgfortran")
        _run(cmd, tmp, "C compiler", code)
        try:
            os.rename(tmp, final)  # atomic publish of the complete folder
        except OSError:
            if not sofile.is_file():  # not a lost race: something else is wrong
                raise
        else:
            tmp = None
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return BuiltModule(code, _load(modname, sofile), sofile, native, cached=False)
