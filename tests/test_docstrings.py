"""Every dotted ``lagcodegen.x.y`` name a docstring (or a comment) cites resolves to what it names: a module
that exists as a file (no alias module), then attributes of it (a class, a function, a method,
a constant, a dataclass field), never a module reached under another name (``lagcodegen.systems``
is ``lagcodegen.model.systems``). An ast walk over the docstrings, and the comments, of the
modules in CHECKED."""

import ast
import dataclasses
import importlib
import io
import re
import tokenize
import types
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "lagcodegen"

#: The files (or folders, every .py below) whose docstrings are checked, relative to the package.
#: Extend it as the other parts are brought in line.
CHECKED = [
    "__init__.py", "__main__.py", "api.py", "sweep.py", "cli", "model", "modelfile", "theory", "derivation.py",
    "result.py", "util.py", "progress.py", "cache.py", "buildstep.py", "errors.py", "version.py",
    "codegen", "formulation", "solvers", "simulation", "build.py", "codes.py", "fmu", "animation.py", "notebook.py",
]

#: A cited name: lagcodegen followed by dotted identifiers, not part of a file name such as
#: ``<prefix>.lagcodegen.json``.
NAME = re.compile(r"(?<![\w.-])lagcodegen(?:\.[A-Za-z_]\w*)+")
#: A Sphinx role naming a lagcodegen object: the object must be of the role's kind.
ROLE = re.compile(r":(func|meth|class|mod):`~?(?:[^`<]*<)?(lagcodegen(?:\.[A-Za-z_]\w*)+)>?`")
#: File names that look like dotted names.
FILE_SUFFIXES = (".json", ".h", ".c", ".f90", ".toml", ".py", ".cmake", ".j2")


def checked_files() -> list[Path]:
    files = []
    for item in CHECKED:
        path = PACKAGE / item
        files += sorted(path.rglob("*.py")) if path.is_dir() else [path]
    return files


def docstrings(path: Path):
    """(line, text) of the module's, classes' and functions' docstrings."""
    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                yield body[0].lineno, body[0].value.value


def comments(path: Path):
    """(line, text) of the module's comments (``#`` and ``#:``)."""
    with io.open(path, encoding="utf-8") as fh:
        for tok in tokenize.generate_tokens(fh.readline):
            if tok.type == tokenize.COMMENT:
                yield tok.start[0], tok.string


def problem(name: str) -> str | None:
    """None if ``name`` resolves, else what is wrong."""
    parts = name.split(".")
    module, depth = None, 0
    for i in range(len(parts), 0, -1):
        try:
            module = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        depth = i
        break
    if module is None:
        return "no such module"
    obj = module
    for i in range(depth, len(parts)):
        attr = parts[i]
        if isinstance(obj, type) and dataclasses.is_dataclass(obj) and attr in obj.__dataclass_fields__:
            return None if i == len(parts) - 1 else f"{'.'.join(parts[:i + 1])} is a field"
        if not hasattr(obj, attr):
            return f"{'.'.join(parts[:i])} has no {attr!r}"
        obj = getattr(obj, attr)
        if isinstance(obj, types.ModuleType) and obj.__name__ != ".".join(parts[:i + 1]):
            return f"{'.'.join(parts[:i + 1])} is the module {obj.__name__} under another name"
    return None


def resolve(name: str):
    """The object ``name`` names (after :func:`problem` found nothing wrong)."""
    obj, parts = None, name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attr in parts[i:]:
            obj = getattr(obj, attr, None)
        return obj


def kind_problem(role: str, name: str) -> str | None:
    """None if the object ``name`` names is of the kind ``role`` says (func, meth, class, mod)."""
    obj = resolve(name)
    if role == "mod" and not isinstance(obj, types.ModuleType):
        return f":mod: names a {type(obj).__name__}, not a module"
    if role == "class" and not isinstance(obj, type):
        return f":class: names a {type(obj).__name__}, not a class"
    if role in ("func", "meth") and (isinstance(obj, types.ModuleType) or not callable(obj)):
        return f":{role}: names a {type(obj).__name__}, not a function"
    return None


def cited_roles():
    for path in checked_files():
        for line, text in docstrings(path):
            for m in ROLE.finditer(text):
                yield f"{path.relative_to(ROOT)}:{line + text[:m.start()].count(chr(10))}", m.group(1), m.group(2)


def cited_names():
    for path in checked_files():
        for line, text in [*docstrings(path), *comments(path)]:
            for m in NAME.finditer(text):
                name = m.group(0)
                if any(name.endswith(s) for s in FILE_SUFFIXES):
                    continue
                yield f"{path.relative_to(ROOT)}:{line + text[:m.start()].count(chr(10))}", name


def test_checked_files_exist():
    missing = [item for item in CHECKED if not (PACKAGE / item).exists()]
    assert not missing, missing


def test_the_checker_finds_wrong_names():
    assert problem("lagcodegen.model.systems.pendulum") is None
    assert problem("lagcodegen.modelfile.ModelFile.simulate") is None
    assert problem("lagcodegen.modelfile.SimulationSettings.t_end") is None
    assert "has no" in problem("lagcodegen.dae")
    assert "under another name" in problem("lagcodegen.systems.pendulum")
    assert "has no" in problem("lagcodegen.solvers.simulate_nothing")
    assert kind_problem("func", "lagcodegen.build") and not kind_problem("mod", "lagcodegen.build")
    assert not kind_problem("func", "lagcodegen.build.build") and kind_problem("class", "lagcodegen.build.build")
    assert ("func", "lagcodegen.compile_file") in {(r, n) for _, r, n in cited_roles()}
    names = {name for _, name in cited_names()}
    assert "lagcodegen.compile_file" in names and "lagcodegen.model.events.Event" in names


def test_roles_name_objects_of_their_kind():
    wrong = [f"{where}: :{role}:`{name}`: {kind_problem(role, name)}" for where, role, name in cited_roles()
             if not problem(name) and kind_problem(role, name)]
    assert not wrong, "docstrings naming an object of another kind:\n" + "\n".join(wrong)


def test_docstrings_cite_names_that_exist():
    wrong = [f"{where}: {name}: {problem(name)}" for where, name in cited_names() if problem(name)]
    assert not wrong, "docstrings citing names that do not resolve:\n" + "\n".join(wrong)
