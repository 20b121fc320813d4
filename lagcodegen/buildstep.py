"""lagcodegen as a step of another project's build (CMake, Meson, Make, Ninja).

* Model sources: a TOML model file (parsed, never executed), or a function in a Python file,
  ``path/to/models.py:double_pendulum``, returning a :class:`~lagcodegen.model.Model`, a
  :class:`~lagcodegen.theory.constraints.ConstrainedSystem` or a
  :class:`~lagcodegen.modelfile.ModelFile`. A Python model file is **executed** (as the user's
  own code, with its folder on ``sys.path`` while it runs): only name files you trust.
* The manifest ``<prefix>.lagcodegen.json`` in the output folder records the digest of the
  inputs (the model file and, for Python models, the modules it imported from its own folder),
  the options, the versions of lagcodegen, sympy and symengine, a digest of lagcodegen's own
  sources and templates, and the digest of every file written. When it matches, ``generate``,
  ``generate --check`` and ``generate --list-outputs`` answer without deriving the model.
  When it does not, ``--check`` derives and compares; a manifest that differs only in the
  generator record (same files from another lagcodegen, sympy or symengine) is not stale.
* The depfile (Make syntax, for Ninja, Make, CMake's ``DEPFILE`` and Meson's ``depfile:``) names
  the model's inputs and lagcodegen's own files; the stamp file is touched on every successful
  run, so that a build tool sees the step done even when no generated file changed (unchanged
  files are never rewritten).
* :func:`cmake_dir`: the folder of the CMake package (``find_package(lagcodegen CONFIG)``,
  ``lagcodegen_generate()``).
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path, PureWindowsPath
from typing import Mapping

from .errors import ModelError
from .modelfile import ModelFile, load_model_path
from .modelfile.formats import as_model_file
from .util import atomic_write, excerpt, read_regular_file
from .version import __version__

#: Version of the manifest's layout.
MANIFEST_FORMAT = 1
PACKAGE_DIR = Path(__file__).resolve().parent


def cmake_dir() -> Path:
    """Folder holding ``lagcodegenConfig.cmake`` (pass it as ``lagcodegen_DIR``)."""
    return PACKAGE_DIR / "cmake"


@dataclass
class ModelSource:
    """A loaded model source: the ModelFile, the name used for the manifest and every input
    file the generated code depends on (the file itself first)."""

    model_file: ModelFile
    spec: str
    inputs: list[Path] = field(default_factory=list)


def split_python_spec(spec: str) -> tuple[str, str] | None:
    """(file, function) of ``file.py:function``, or None for any other model argument."""
    path, sep, func = str(spec).rpartition(":")
    if sep and path.endswith(".py") and func.isidentifier():
        return path, func
    if str(spec).endswith(".py"):
        raise ModelError(f"{spec}: name the function returning the model, as in {spec}:my_model")
    return None


def load_source(spec: str, *, urdf: Mapping | None = None) -> ModelSource:
    """The model named by ``spec``: a model file (:func:`lagcodegen.modelfile.load_model_path`,
    by its suffix; ``urdf``: a URDF file's loading options), or ``file.py:function`` (executes
    the file)."""
    python = split_python_spec(spec)
    if python is None:
        path = Path(spec)
        return ModelSource(load_model_path(path, urdf=urdf), path.name, [path.resolve()])
    if urdf:
        raise ModelError(f"{spec}: URDF options apply to .urdf files only")
    return load_python_model(*python)


def load_python_model(path: str | os.PathLike, function: str) -> ModelSource:
    """Execute the Python file ``path`` and call ``function()`` (no arguments) for the model.

    The file's folder is on ``sys.path`` while it runs, so it may import its neighbours; those
    modules are inputs too (their digests enter the manifest, their paths the depfile)."""
    file = Path(path).resolve()
    if not file.is_file():
        raise ModelError(f"{path}: no such Python model file")
    folder = file.parent
    before = set(sys.modules)
    name = f"_lagcodegen_model_{hashlib.sha256(str(file).encode()).hexdigest()[:12]}"
    spec = importlib.util.spec_from_file_location(name, file)
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(folder))
    try:
        spec.loader.exec_module(module)
        func = getattr(module, function, None)
        if not callable(func):
            raise ModelError(f"{path}: defines no function {function!r}")
        value = func()
    except ModelError:
        raise
    except Exception as exc:  # the user's code: report it as bad input, with its type
        raise ModelError(f"{path}:{function}: {type(exc).__name__}: {exc}") from exc
    finally:
        sys.path.remove(str(folder))
        # The modules the file imported from its folder are inputs; they leave sys.modules again,
        # so that loading the model a second time in one process reads them anew.
        inputs = [file]
        for mod in sorted(set(sys.modules) - before):
            origin = getattr(sys.modules[mod], "__file__", None)
            if origin and Path(origin).resolve().is_relative_to(folder):
                if Path(origin).resolve() != file:
                    inputs.append(Path(origin).resolve())
                del sys.modules[mod]
    return ModelSource(as_model_file(value, file, f"{path}:{function}"), f"{file.name}:{function}", inputs)


# --------------------------------------------------------------------------- manifest
def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def own_files() -> list[Path]:
    """lagcodegen's sources, templates and CMake files: a change to any of them regenerates."""
    roots = [PACKAGE_DIR]
    templates = PACKAGE_DIR / "templates"
    if not templates.is_dir():
        templates = PACKAGE_DIR.parent / "templates"  # the source tree of an editable install
    roots.append(templates)
    files = []
    for root in roots:
        for path in sorted(root.rglob("*")):
            if path.is_file() and path.suffix in (".py", ".j2", ".h", ".c", ".cmake") and \
                    "__pycache__" not in path.parts:
                files.append(path)
    return sorted(set(files))


def generator_record() -> dict:
    """Versions of lagcodegen, sympy and symengine, and a digest of lagcodegen's own files."""
    import symengine
    import sympy

    h = hashlib.sha256()
    for path in own_files():
        h.update(path.relative_to(PACKAGE_DIR.parent).as_posix().encode() + b"\0")
        h.update(path.read_bytes())
    return {"lagcodegen": __version__, "sympy": sympy.__version__, "symengine": symengine.__version__,
            "sources": h.hexdigest()}


def input_record(source: ModelSource) -> dict:
    """The model's name and the digests of its input files (names relative to the first's folder)."""
    base = source.inputs[0].parent
    files = {}
    for path in source.inputs:
        rel = os.path.relpath(path, base).replace(os.sep, "/")
        files[rel] = _digest(path.read_bytes())
    return {"model": source.spec, "files": files}


def manifest_name(prefix: str) -> str:
    return f"{prefix}.lagcodegen.json"


def manifest_text(inputs: dict, options: Mapping, generator: dict, files: Mapping[str, str]) -> str:
    """The manifest (deterministic JSON) of ``files`` (name -> text) generated from ``inputs``."""
    record = {"format": MANIFEST_FORMAT, "generator": generator, "inputs": inputs, "options": dict(options),
              "files": {name: _digest(text.encode("utf-8")) for name, text in sorted(files.items())}}
    return json.dumps(record, indent=2, sort_keys=True) + "\n"


class ManifestError(ModelError):
    """A manifest lists a file name that is not a plain name inside its folder."""


def check_manifest_name(name, manifest: Path) -> str:
    """``name`` if it names a file inside the manifest's folder: a relative name of components of
    letters, digits and ``_ . + -`` separated by ``/`` (what lagcodegen writes); ManifestError for
    an absolute name, a drive, ``..``, ``.``, an empty component or any other character (a
    backslash, a control character, CMake's list separator ``;``): a tampered manifest must not
    make ``--list-outputs``, ``--check`` or a build tool's clean target reach outside the folder."""
    problem = None
    if not isinstance(name, str) or not name:
        problem = "is not a file name"
    elif name.startswith("/") or PureWindowsPath(name).drive or PureWindowsPath(name).root:
        problem = "is an absolute path"
    elif any(part in ("", ".", "..") for part in name.split("/")):
        problem = "is not a plain name inside the folder ('..', '.' or an empty component)"
    elif not all(ch.isalnum() or ch in "_.+-/" for ch in name):
        problem = "has a character other than letters, digits and _ . + - / (a list separator, a space, a quote)"
    if problem:
        raise ManifestError(f"{manifest}: the listed file {excerpt(name)} {problem}: the manifest was not written "
                            "by lagcodegen; delete it to regenerate the folder")
    return name


def read_manifest(directory: Path, prefix: str) -> dict | None:
    """The manifest of ``directory``, None if there is none (or it is not JSON of this format);
    ManifestError if it lists a file outside the folder (:func:`check_manifest_name`)."""
    path = Path(directory) / manifest_name(prefix)
    data = read_regular_file(path)
    if data is None:
        return None
    try:
        record = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError):
        return None
    if not (isinstance(record, dict) and record.get("format") == MANIFEST_FORMAT):
        return None
    files = record.get("files")
    if isinstance(files, dict):
        root = os.path.realpath(directory)
        for name, digest in files.items():
            check_manifest_name(name, path)
            target = Path(directory) / name
            inside = os.path.commonpath([root, os.path.realpath(target.parent)]) == root
            if not inside or (os.path.lexists(target) and not target.is_file()) or target.is_symlink():
                raise ManifestError(f"{path}: the listed file {excerpt(name)} is not a regular file inside "
                                    f"{directory} (a link, a FIFO, a folder): the manifest was not written by "
                                    "lagcodegen; delete it to regenerate the folder")
            if not isinstance(digest, str):
                raise ManifestError(f"{path}: the digest of {excerpt(name)} is not a string: the manifest was not "
                                    "written by lagcodegen; delete it to regenerate the folder")
    return record


def manifest_matches(record: dict | None, inputs: dict, options: Mapping, generator: dict) -> bool:
    """The manifest was written for these inputs, options and generator."""
    return (record is not None and record.get("inputs") == inputs and record.get("options") == dict(options)
            and record.get("generator") == generator and isinstance(record.get("files"), dict))


def manifest_outdated(directory: Path, prefix: str, text: str) -> bool:
    """The manifest in ``directory`` records other inputs, options or files than ``text`` (a new
    manifest). Another generator alone (a lagcodegen, sympy or symengine that writes the same
    files) does not make a folder out of date."""
    record = read_manifest(directory, prefix)
    new = json.loads(text)
    return record is None or {k: v for k, v in record.items() if k != "generator"} != \
        {k: v for k, v in new.items() if k != "generator"}


def stale_by_manifest(directory: Path, record: dict) -> list[str]:
    """Files the manifest lists that are missing, differ from their recorded digest, or are not
    regular files (a symbolic link, a FIFO: never followed or read)."""
    stale = []
    for name, digest in sorted(record["files"].items()):
        data = read_regular_file(Path(directory) / name)  # a link, FIFO or folder is stale, never read
        if data is None or _digest(data) != digest:
            stale.append(name)
    return stale


# --------------------------------------------------------------------------- depfile and stamp
def _make_escape(path: str) -> str:
    out = path.replace("\\", "/") if os.sep == "\\" else path
    return out.replace("$", "$$").replace("#", "\\#").replace(" ", "\\ ")


def write_depfile(depfile: str | os.PathLike, targets: list[str], inputs: list[Path]) -> None:
    """Write a Make-syntax depfile: ``targets`` (as given: a build tool compares the first with
    its own output path) depend on the model's inputs and on lagcodegen's own files."""
    deps = [str(p) for p in inputs] + [str(p) for p in own_files()]
    lines = [" ".join(_make_escape(t) for t in targets) + ": \\"]
    lines += [f"  {_make_escape(d)} \\" for d in deps[:-1]] + [f"  {_make_escape(deps[-1])}"]
    path = Path(depfile)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = "\n".join(lines) + "\n"
    if not (path.is_file() and path.read_text(encoding="utf-8") == text):
        atomic_write(path, text)


def touch_stamp(stamp: str | os.PathLike, text: str) -> None:
    """Write the stamp file and set its modification time to now (even when its text is the same)."""
    path = Path(stamp)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not (path.is_file() and path.read_text(encoding="utf-8") == text):
        atomic_write(path, text)
    os.utime(path, None)
