"""Compile generated code into an importable cffi module, cached by content hash.

The cache key covers the sources, the compiler (path and version), the flags, the
lagcodegen version and the SUNDIALS libraries linked. A build runs in a private temporary
folder that is renamed into the cache when complete, so a cached module is never seen half
written, and two processes building the same model at once both succeed (the second
rename loses the race and that process uses the winner's files).

The cache's rules of trust are :mod:`lagcodegen.cache`'s.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import ctypes
import functools
import io
import importlib.machinery
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import sysconfig
from dataclasses import dataclass
from pathlib import Path

import cffi

from .codegen.cffi_decl import model_cdef, runtime_cdef
from .codegen.languages import backend, file_backend
from .codegen.signatures import DRIVERS
from .codegen.signatures import c_header as types_header
from .codegen.record import GeneratedCode
from .codegen.tables import dae_table, model_table
from .codes import c_header
from .cache import (ABANDONED_BUILD_SECONDS, CACHE_FORMAT, DIGEST_NAME, STALE_BUILD_SECONDS, CacheWarning,
                    cache_dir, cache_key, cached_build, clean_stale, import_module, open_library)
from . import progress
from .errors import CompileError, LagcodegenError
from .runtime import sources as runtime_files
from .version import __version__

#: The cache's names stay importable from here (lagcodegen.cache holds them).
__all__ = ["ABANDONED_BUILD_SECONDS", "CACHE_FORMAT", "DIGEST_NAME", "STALE_BUILD_SECONDS", "CacheWarning",
           "BuiltModule", "Sundials", "build", "cache_dir", "clean_stale", "compiler_id", "driver_sources",
           "find_sundials", "runtime", "runtime_sources", "config_header", "generated_headers", "table_source", "dae_table_source", "DEFAULT_CFLAGS",
           "DEFAULT_FFLAGS", "driver_runtime", "plain_library"]

DEFAULT_CFLAGS = ("-O2", "-fPIC", "-std=c99")
#: A model library's flags when the caller keeps DEFAULT_CFLAGS (the runtime's drivers stay at
#: -O2): -O1 integrates in 0.99-1.04x the time of -O2 (double pendulum, 5- and 8-link chains,
#: Adams and BDF; -Og 1.18-1.28x, -O0 1.2-1.55x) and compiles the double pendulum in 0.13 s
#: instead of 0.15 s (gcc 12); LCG_COLD_JACOBIAN compiles the dense Jacobian at -O0 under gcc
#: (model.c.j2: run times 0.99-1.03x, the 8-link chain's build 0.59 -> 0.22 s).
MODEL_CFLAGS = ("-O1", "-fPIC", "-std=c99", "-DLCG_COLD_JACOBIAN")
DEFAULT_FFLAGS = ("-O2", "-fPIC", "-std=f2008", "-ffp-contract=off")  # no FMA: same numbers as C


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
    """Locate the SUNDIALS libraries of the installed scikit-sundae wheel (found, not imported:
    importing sksundae imports scipy.optimize, about a second)."""
    spec = importlib.util.find_spec("sksundae")
    if spec is None or not spec.submodule_search_locations:  # pragma: no cover - dependency
        raise LagcodegenError("scikit-sundae is not installed: pip install scikit-sundae")
    pkg = Path(list(spec.submodule_search_locations)[0]).resolve()
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


#: The model-independent native drivers, real C files of lagcodegen/runtime/ compiled once per
#: installation: CVODE for ODEs (lcg_cvode.c), CVODE for the index-1 constrained equations
#: (lcg_cvc.c), IDA for the GGL form (lcg_ida.c); each lcg_<name>.c with its header lcg_<name>.h,
#: and its structs in lcg_<name>_types.h (signatures.DRIVERS[name]).
SUNDIALS_DRIVERS = ("cvode", "cvc", "ida")
#: The input tables the drivers read (lcg_inputs.h; structs in lcg_inputs_types.h).
INPUTS_FILES = ("lcg_inputs.h", "lcg_inputs.c")
#: The runtime's C files and the headers its cffi module includes.
RUNTIME_C_FILES = tuple(f"lcg_{d}.c" for d in SUNDIALS_DRIVERS)
RUNTIME_HEADERS = tuple(f"lcg_{d}.h" for d in SUNDIALS_DRIVERS)
#: Every file of lagcodegen/runtime/ the runtime is compiled from: the drivers and what they share.
RUNTIME_FILES = ("lcg_model.h", "lcg_dae_model.h", "lcg_control.h", "lcg_pool.h", "lcg_sundials.h", "sundials_api.h",
                 *RUNTIME_HEADERS, *RUNTIME_C_FILES, *INPUTS_FILES)
#: The headers of a model's function table (its library compiles them with its table).
TABLE_FILES = ("lcg_model.h",)
DAE_TABLE_FILES = ("lcg_model.h", "lcg_dae_model.h")


def config_header(sundials: Sundials) -> str:
    """``lcg_config.h``: what the runtime's sources take from the build -- the SUNDIALS index type
    of the bundled libraries (sundials_api.h) and the versions."""
    return (f"/* lcg_config.h -- generated by lagcodegen {__version__}: the build's configuration of the runtime. */\n"
            "#ifndef LCG_CONFIG_H\n#define LCG_CONFIG_H\n\n"
            f'#define LCG_VERSION "{__version__}"\n'
            f'#define LCG_SUNDIALS_VERSION "{sundials.version}"\n'
            "/* sunindextype of the SUNDIALS libraries (sksundae/c_config.pxi) */\n"
            f"#define LCG_SUNINDEXTYPE {sundials.sunindextype}\n\n#endif /* LCG_CONFIG_H */\n")


def generated_headers() -> dict[str, str]:
    """The headers rendered from Python declarations that the runtime's files and the model tables
    include: ``lcg_codes.h`` (:func:`lagcodegen.codes.c_header`)."""
    return {"lcg_codes.h": c_header()}


#: The drivers whose structs the runtime's generated headers declare (lcg_<name>_types.h; "dae":
#: the events record of the constrained drivers).
RUNTIME_DRIVERS = ("dae", *SUNDIALS_DRIVERS, "inputs")


def types_headers(names=RUNTIME_DRIVERS) -> dict[str, str]:
    """``lcg_<driver>_types.h``: the structs of the drivers ``names``, rendered from their one
    declaration (:data:`lagcodegen.codegen.signatures.DRIVERS`)."""
    return {DRIVERS[n].header_name: types_header(DRIVERS[n], __version__) for n in names}


def runtime_sources(sundials: Sundials) -> dict[str, str]:
    """The model-independent native drivers (taking a model's function table, lcg_model.h, or a
    constrained model's, lcg_dae_model.h) and the SUNDIALS declarations they are written against:
    the files of lagcodegen/runtime/ as they are, with the generated ``lcg_config.h``,
    ``lcg_codes.h`` and ``lcg_<driver>_types.h``."""
    return {**runtime_files(RUNTIME_FILES), "lcg_config.h": config_header(sundials), **generated_headers(),
            **types_headers()}


def table_source(code: GeneratedCode) -> dict[str, str]:
    """``<prefix>_table.c``: the function table of ``code`` (lcg_model.h) and ``lcg_model.h``."""
    return {**runtime_files(TABLE_FILES), **generated_headers(), f"{code.prefix}_table.c": model_table(code)}


def dae_table_source(code: GeneratedCode) -> dict[str, str]:
    """``<prefix>_dae_table.c``: the function table of constrained ``code`` (``code.dae``;
    lcg_dae_model.h, which it includes, with lcg_model.h)."""
    table = dae_table(code)
    return {**runtime_files(DAE_TABLE_FILES), **generated_headers(), f"{code.prefix}_dae_table.c": table}


def driver_sources(code: GeneratedCode, sundials: Sundials) -> dict[str, str]:
    """Everything ``code`` needs besides its own files to run on the native drivers: the
    model-independent drivers (:func:`runtime_sources`) and the model's tables (:func:`table_source`,
    and :func:`dae_table_source` for constrained code)."""
    tables = {**table_source(code), **(dae_table_source(code) if code.dae is not None else {})}
    return {**runtime_sources(sundials), **tables}


@dataclass(frozen=True)
class BuiltModule:
    """A compiled, loaded model: the code it was built from, where it lives, whether it came from
    the cache. :class:`lagcodegen.simulation.ode.CompiledModel` wraps it.

    Either ``module`` is the model's own cffi module (code with drivers of its own, or built
    without SUNDIALS), or (``table`` set) ``module`` is the model-independent runtime
    (:func:`runtime`) and ``table`` the ``const lcg_model *`` of the model's library at ``path``
    (no Python.h in it), kept open by ``library``; for constrained code ``dae_table`` is the
    library's ``const lcg_dae_model *`` too."""

    code: GeneratedCode
    module: object
    path: Path
    native: bool
    cached: bool
    table: object = None
    library: object = None
    dae_table: object = None


def _run(cmd: list[str], cwd: Path, what: str, label: str) -> None:
    try:
        proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=1800)
    except OSError as exc:
        raise CompileError(f"cannot run the {what} {cmd[0]!r}", cmd, str(exc)) from None
    if proc.returncode != 0:
        raise CompileError(f"compiling {label} failed ({what}, exit {proc.returncode})",
                           cmd, proc.stdout + proc.stderr)


def _run_all(cmds: list[list[str]], cwd: Path, what: str, label: str, stage=progress.OFF) -> None:
    """Run the compiler commands ``cmds`` at once (as many as there are cores), each to its end;
    ``stage`` advances (in the calling thread) as each one ends."""
    if len(cmds) <= 1 or (os.cpu_count() or 1) == 1:
        for cmd in cmds:
            _run(cmd, cwd, what, label)
            stage.advance()
        return
    with concurrent.futures.ThreadPoolExecutor(max_workers=min(len(cmds), os.cpu_count() or 1)) as pool:
        for future in concurrent.futures.as_completed([pool.submit(_run, cmd, cwd, what, label) for cmd in cmds]):
            future.result()
            stage.advance()


def _write(folder: Path, sources: dict[str, str]) -> None:
    for name, text in sources.items():
        (folder / name).write_text(text)


def _cffi_module(folder: Path, modname: str, cdef: str, headers: list[str]) -> str:
    """Write the cffi wrapper ``<modname>.c`` including ``headers`` into ``folder``."""
    ffi = cffi.FFI()
    ffi.cdef(cdef)
    ffi.set_source(modname, "".join(f'#include "{h}"\n' for h in headers))
    with contextlib.redirect_stdout(io.StringIO()):  # cffi announces the file it writes
        ffi.emit_c_code(str(folder / f"{modname}.c"))
    return f"{modname}.c"


def _languages(sources) -> list:
    """The backends of the model sources among ``sources`` (by their files' suffixes), each once."""
    found = {}
    for name in sources:
        be = file_backend(name)
        if be is not None:
            found.setdefault(be.name, be)
    return [found[k] for k in sorted(found)]


def _apart(sources) -> list:
    """The backends among ``sources`` whose model sources are not C (:func:`_languages`): compiled
    apart into objects (:func:`_objects_apart`), with their compiler's identity in the cache key."""
    return [be for be in _languages(sources) if not be.c_sources]


def _objects_apart(folder: Path, sources: dict[str, str], fc: str, fflags, label: str) -> list[str]:
    """The objects of the model sources that are not C (:func:`_apart`), each compiled with ``fc``
    and ``fflags`` (the backend names the compiler in its messages)."""
    objects = []
    for be in _apart(sources):
        for name in sorted(n for n in sources if n.endswith(be.suffix)):  # modules first: sorted names
            obj = name[:-len(be.suffix)] + ".o"
            _run([fc, *fflags, "-c", name, "-o", obj], folder, be.compiler_label, label)
            objects.append(obj)
    return objects


def _compiler(lang: str, given: str | None) -> str:
    """The compiler of ``lang``'s sources: ``given``, else the one its backend's environment
    variable names, else the backend's default."""
    be = backend(lang)
    return given or os.environ.get(be.compiler_env) or be.default_compiler


#: Sources at most this large compile in one compiler call; larger ones file by file, in parallel.
ONE_CALL_BYTES = 200_000


def split_parts(groups: int) -> int:
    """How many objects a source cut into ``groups`` groups of functions compiles as (one per core,
    at most one per group; 1: the file as one translation unit)."""
    return max(1, min(groups, os.cpu_count() or 1))


def _compile_shared(folder: Path, c_files: list[str], objects: list[str], out: str, cc: str, cflags,
                    includes: list[str], libs: list[str], label: str, parallel: bool = False,
                    split: dict | None = None) -> None:
    """Compile ``c_files`` (and link ``objects``) into the shared library ``out``: one compiler
    call for small sources (unless ``parallel``), else one per file at once on every core, then a
    link. A file of ``split`` (name -> groups, :attr:`GeneratedCode.split`) compiles as
    :func:`split_parts` objects at once (``-DLCG_PARTS=K -DLCG_PART=k``)."""
    # No -I on the build folder: the generated files include each other with quotes (found
    # beside the includer), so a model named math, stdlib or Python never shadows <math.h>.
    jobs = []  # (source, extra flags, object)
    for f in c_files:
        parts = split_parts((split or {}).get(f, 1))
        if parts == 1:
            jobs.append((f, [], f[:-2] + ".o"))
        else:
            jobs += [(f, [f"-DLCG_PARTS={parts}", f"-DLCG_PART={k}"], f"{f[:-2]}.part{k}.o") for k in range(parts)]
    size = sum((folder / f).stat().st_size for f in c_files)
    one = ((size <= ONE_CALL_BYTES and not parallel) or len(c_files) == 1) and len(jobs) == len(c_files)
    with progress.stage("compile", total=1 if one else len(jobs) + 1, unit=f"compiler runs, {label}") as stage:
        if one:
            _run([cc, *cflags, "-shared", *includes, *c_files, *objects, "-o", out, *libs], folder, "C compiler",
                 label)
            stage.advance()
            return
        _run_all([[cc, *cflags, *includes, *extra, "-c", f, "-o", obj] for f, extra, obj in jobs], folder,
                 "C compiler", label, stage)
        _run([cc, *cflags, "-shared", *[obj for _, _, obj in jobs], *objects, "-o", out, *libs], folder,
             "C compiler", label)
        stage.advance()


def _python_include() -> str:
    return f"-I{sysconfig.get_paths()['include']}"


def runtime_key(cc: str, cflags: tuple[str, ...], sundials: Sundials) -> str:
    """The cache key of the runtime: the sources' text (the files of lagcodegen/runtime/ as they
    are, and the generated headers), the cffi declarations, compiler, flags, Python, SUNDIALS."""
    link = sundials.link_args(("cvode", "ida", "core"))
    ext = importlib.machinery.EXTENSION_SUFFIXES[0]
    texts = [f"{name}\0{text}" for name, text in sorted(runtime_sources(sundials).items())]
    return cache_key([__version__, f"cache format {CACHE_FORMAT}", "runtime", compiler_id(cc), " ".join(cflags),
                      " ".join(link), ext, runtime_cdef(), sys.version, sundials.sunindextype, sundials.version,
                      *texts])


@functools.lru_cache(maxsize=4)
def _runtime_module(cc: str, cflags: tuple[str, ...]):
    sundials = find_sundials()
    cdef = runtime_cdef()
    link = sundials.link_args(("cvode", "ida", "core"))
    ext = importlib.machinery.EXTENSION_SUFFIXES[0]
    key = runtime_key(cc, cflags, sundials)
    modname = f"_lcg_runtime_{key}"

    def make(tmp: Path) -> Path:
        _write(tmp, runtime_sources(sundials))
        wrapper = _cffi_module(tmp, modname, cdef, list(RUNTIME_HEADERS))
        _compile_shared(tmp, [wrapper, *RUNTIME_C_FILES, *INPUTS_FILES[1:]], [], f"{modname}{ext}", cc, cflags,
                        [_python_include()], [*link, "-lm", "-pthread"], "the lagcodegen runtime", parallel=True)
        return tmp / f"{modname}{ext}"

    return cached_build(key, modname, f"{modname}{ext}", make, import_module)[0]


def runtime(cc: str | None = None, cflags: tuple[str, ...] = DEFAULT_CFLAGS):
    """The model-independent runtime: a cffi module with the native drivers -- CVODE taking a
    model's function table (lcg_model.h), CVODE (index 1) and IDA (GGL) taking a constrained
    model's (lcg_dae_model.h) -- built into the cache once per lagcodegen version, compiler,
    flags, Python and SUNDIALS libraries (the first call builds it, a few seconds; later ones
    load it)."""
    cc = cc or os.environ.get("CC") or "cc"
    return _runtime_module(cc, tuple(cflags))


def driver_runtime(label: str, key_texts: list[str], render, cdef: str, header: str, libs: list[str],
                   cc: str | None = None, cflags: tuple[str, ...] = DEFAULT_CFLAGS, units: tuple[str, ...] = ()):
    """A model-independent driver as a cffi module of its own, built into the cache once per
    lagcodegen version, compiler, flags and Python (as :func:`runtime`; e.g. the Taylor driver,
    :mod:`lagcodegen.solvers.taylor`): ``render()`` returns its sources (called only to build),
    ``key_texts`` what they are rendered from, ``cdef`` its interface, ``header`` the header the
    wrapper includes, ``libs`` what it links, ``units`` the C files compiled (empty: every ``.c``
    of the sources; a unit may include another C file, which then is not compiled on its own).
    Not memoized: the caller keeps the module."""
    cc = cc or os.environ.get("CC") or "cc"
    ext = importlib.machinery.EXTENSION_SUFFIXES[0]
    key = cache_key([__version__, f"cache format {CACHE_FORMAT}", f"{label} runtime", compiler_id(cc),
                     " ".join(cflags), " ".join(libs), ext, cdef, sys.version, header, *units, *key_texts])
    modname = f"_lcg_{label}_runtime_{key}"

    def make(tmp: Path) -> Path:
        sources = render()
        _write(tmp, sources)
        wrapper = _cffi_module(tmp, modname, cdef, [header])
        c_files = [wrapper] + (list(units) or sorted(n for n in sources if n.endswith(".c")))
        _compile_shared(tmp, c_files, [], f"{modname}{ext}", cc, cflags, [_python_include()], libs,
                        f"the lagcodegen {label} runtime")
        return tmp / f"{modname}{ext}"

    return cached_build(key, modname, f"{modname}{ext}", make, import_module)[0]


def plain_library(label: str, prefix: str, sources: dict[str, str], cc: str | None = None,
                  cflags: tuple[str, ...] = DEFAULT_CFLAGS, libs: tuple[str, ...] = ("-lm",),
                  verbose: bool = False):
    """The C files of ``sources`` compiled into a shared library without Python.h (cached by
    content like every build; loaded only when its digest matches), opened with ctypes: (the
    ctypes library, its path, whether it came from the cache). ``label`` names what it is in
    messages, ``prefix`` in its file name."""
    cc = cc or os.environ.get("CC") or "cc"
    key = cache_key([__version__, f"cache format {CACHE_FORMAT}", "plain library", compiler_id(cc),
                     " ".join(cflags), " ".join(libs), *sorted(f"{k}\0{v}" for k, v in sources.items())])
    modname = f"lib_lcg_{prefix}_{key}"
    filename = f"{modname}.so"

    def make(tmp: Path) -> Path:
        _write(tmp, sources)
        if verbose:
            print("lagcodegen: compiling", prefix, "...", file=sys.stderr, flush=True)
        c_files = sorted(n for n in sources if n.endswith(".c"))
        _compile_shared(tmp, c_files, [], filename, cc, cflags, [], list(libs), label)
        return tmp / filename

    return cached_build(key, modname, filename, make, open_library)


def _uses_runtime(code: GeneratedCode, native: bool) -> bool:
    """Plain model code, or constrained code, on the native drivers: built as a model library for
    the runtime."""
    return native and (code.dae is not None or (not code.cdef_extra and not code.sundials_libs))


def _table(rt, library, getter_name: str, ctype: str):
    """The table a model library's ``getter_name()`` returns, as the runtime's ``ctype``."""
    getter = getattr(library, getter_name)
    getter.restype = ctypes.c_void_p
    getter.argtypes = []
    return rt.ffi.cast(ctype, getter())


def _translation_units(sources: dict[str, str], prefix: str, split: dict) -> tuple[dict[str, str], list[str]]:
    """(``sources`` plus their units, the C files to compile). Where the C is small enough for one
    compiler call, each table compiles in a translation unit ``<file>_unit.c`` with the functions
    it points to (``<prefix>.c`` with ``<prefix>_table.c``, ``<prefix>_dae.c`` with
    ``<prefix>_dae_table.c``): one compiler and assembler run less per table (about 20 ms each).
    The tables define no static names and read no macro of their partners. Files cut into parts
    (``split``) stay as they are."""
    c_files = sorted(n for n in sources if n.endswith(".c"))
    if sum(len(sources[n]) for n in c_files) > ONE_CALL_BYTES:
        return sources, c_files
    out = dict(sources)
    for source, table in ((f"{prefix}.c", f"{prefix}_table.c"), (f"{prefix}_dae.c", f"{prefix}_dae_table.c")):
        if source in sources and table in sources and source not in split:
            unit = source[:-2] + "_unit.c"
            out[unit] = f'#include "{source}"\n#include "{table}"\n'
            c_files = sorted({*c_files, unit} - {source, table})
    return out, c_files


def _model_library(code: GeneratedCode, cc: str, cflags, fc: str, fflags, verbose: bool) -> BuiltModule:
    """The model's own C (and Fortran) with its function table (and, for constrained code,
    ``<prefix>_dae.c`` and its table ``<prefix>_dae_table.c``) as a shared library without
    Python.h, opened for the runtime's drivers; its tables checked against ``code``."""
    rt = runtime(cc, cflags)
    if tuple(cflags) == DEFAULT_CFLAGS:
        cflags = MODEL_CFLAGS
    sources = {**dict(code.files), **table_source(code)}
    if code.dae is not None:
        sources.update(dae_table_source(code))
    sources, c_files = _translation_units(sources, code.prefix, code.split)
    languages = _languages(sources)
    libs = ["-lm"] + [lib for be in languages for lib in be.link_libs]
    parts = [__version__, f"cache format {CACHE_FORMAT}", "model library", compiler_id(cc), " ".join(cflags),
             " ".join(libs), *sorted(f"{k}\0{v}" for k, v in sources.items())]
    if _apart(sources):
        parts += [compiler_id(fc), " ".join(fflags)]
    key = cache_key(parts)
    modname = f"lib_lcg_{code.prefix}_{key}"
    filename = f"{modname}.so"
    label = f"model {code.model_name!r}"

    def make(tmp: Path) -> Path:
        _write(tmp, sources)
        if verbose:
            print("lagcodegen: compiling", code.prefix, "...", file=sys.stderr, flush=True)
        objects = _objects_apart(tmp, sources, fc, fflags, label)
        _compile_shared(tmp, c_files, objects, filename, cc, cflags, [], libs, label, split=code.split)
        return tmp / filename

    library, path, cached = cached_build(key, modname, filename, make, open_library)
    table = _table(rt, library, f"{code.prefix}_model_table", "const lcg_model *")
    nv = getattr(code, "nv", None)  # generalized speeds: the table counts the speeds (lcg_model.h)
    expected = (code.n, code.nz, code.ny, code.np, code.nout) if nv is None else \
        (nv, code.ny - 2 * nv, code.ny, code.np, code.nout)
    if (table.nq, table.nz, table.ny, table.np, table.nout) != expected:
        raise LagcodegenError(f"the library built for model {code.model_name!r} ({path}) has another layout "
                              f"than its code: (nq, nz, ny, np, nout) = {(table.nq, table.nz, table.ny, table.np, table.nout)}"
                              f", expected {expected}")
    dae_table = None
    if code.dae is not None:
        dae_table = _table(rt, library, f"{code.prefix}_dae_model_table", "const lcg_dae_model *")
        _check_dae_table(rt, dae_table, table, code, path)
    return BuiltModule(code, rt, path, True, cached, table=table, library=library, dae_table=dae_table)


def _check_dae_table(rt, dae, table, code: GeneratedCode, path: Path) -> None:
    """Raise LagcodegenError unless the constrained table ``dae`` is what ``code.dae`` describes
    (and one the runtime's drivers read)."""
    lay, null = code.dae, rt.ffi.NULL
    nv = lay.nq if getattr(lay, "nv", None) is None else lay.nv  # the state y = (q, v): ny = nq + nv
    got = (dae.nq, dae.ny, dae.nj, dae.njh, dae.ng, dae.np, dae.nout, dae.nroot, dae.roots != null,
           dae.ggl_res != null, dae.ggl_jac != null, dae.model == table)
    expected = (lay.nq, lay.nq + nv, lay.nj, lay.njh, lay.ng, lay.np, lay.nout, lay.nroot, lay.nroot > 0, lay.ggl,
                lay.ggl_jac, True)
    message = rt.ffi.new("char[]", 256)
    if got != expected or not rt.lib.lcg_dae_check(dae, message, 256):
        why = rt.ffi.string(message).decode(errors="replace")
        raise LagcodegenError(f"the library built for constrained model {code.model_name!r} ({path}) has another "
                              f"layout than its code: (nq, ny, nj, njh, ng, np, nout, nroot, roots, ggl_res, ggl_jac, "
                              f"model) = {got}, expected {expected}" + (f"; {why}" if why else ""))


def build(code: GeneratedCode, native: bool = True, cc: str | None = None,
          cflags: tuple[str, ...] = DEFAULT_CFLAGS, verbose: bool = False,
          fc: str | None = None, fflags: tuple[str, ...] = DEFAULT_FFLAGS) -> BuiltModule:
    """Compile ``code`` for Python; cached by content hash.

    Plain model code with ``native`` compiles into a shared library of its own (no Python.h, no
    driver) whose function table the model-independent runtime's CVODE driver takes
    (:func:`runtime`, built once); constrained code (``code.dae``) likewise, with its constrained
    table for the runtime's index-1 (CVODE) and GGL (IDA) drivers. Other code (``code.cdef_extra``:
    drivers of its own, e.g. the Taylor integrator; or ``native=False``) becomes a cffi module of
    its own.

    Every ``.c`` file of ``code.files`` is compiled with ``cc``, every ``.f90`` file with ``fc``
    (gfortran; its objects are linked in). ``code.cdef_extra`` adds declarations to the cffi
    interface, ``code.cffi_headers`` the headers the module includes, ``code.sundials_libs``
    the SUNDIALS libraries linked (e.g. "cvode", "ida").
    """
    cc = _compiler("c", cc)
    fc = _compiler("fortran", fc)
    if _uses_runtime(code, native):
        return _model_library(code, cc, cflags, fc, fflags, verbose)
    if code.dae is not None:
        raise LagcodegenError("constrained code runs on the runtime's native drivers: build it with native=True")
    sundials = find_sundials() if native else None
    sources = dict(code.files)
    if native:
        sources["sundials_api.h"] = runtime_files(["sundials_api.h"])["sundials_api.h"]
        sources["lcg_config.h"] = config_header(sundials)
    headers = [code.header_name, *code.cffi_headers]
    apart = _apart(sources)
    cdef = model_cdef(code, native) + "\n" + code.cdef_extra
    link = sundials.link_args(("cvode", *code.sundials_libs, "core")) if native else []
    ext = importlib.machinery.EXTENSION_SUFFIXES[0]
    parts = [__version__, f"cache format {CACHE_FORMAT}", compiler_id(cc), " ".join(cflags), " ".join(link),
             ext, cdef, sys.version, *headers, *sorted(f"{k}\0{v}" for k, v in sources.items())]
    if apart:
        parts += [compiler_id(fc), " ".join(fflags)]
    key = cache_key(parts)
    modname = f"_lcg_{code.prefix}_{key}"
    label = f"model {code.model_name!r}"

    def make(tmp: Path) -> Path:
        _write(tmp, sources)
        wrapper = _cffi_module(tmp, modname, cdef, headers)
        if verbose:
            print("lagcodegen: compiling", code.prefix, "...", file=sys.stderr, flush=True)
        objects = _objects_apart(tmp, sources, fc, fflags, label)
        c_files = [wrapper] + sorted(n for n in sources if n.endswith(".c"))
        libs = [*link, "-lm"] + [lib for be in _languages(sources) for lib in be.link_libs]
        _compile_shared(tmp, c_files, objects, f"{modname}{ext}", cc, cflags, [_python_include()], libs, label,
                        split=code.split)
        return tmp / f"{modname}{ext}"

    module, path, cached = cached_build(key, modname, f"{modname}{ext}", make, import_module)
    return BuiltModule(code, module, path, native, cached)
