"""The package layout is the pipeline: imports run one way, down the stages, with no circle and
no private name crossing a subpackage. An ast walk over every module (imports inside functions
count too), so that the layout stays true as the code grows."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "lagcodegen"

#: The stages, lowest first. A module may import from its own stage (without a circle) or from
#: a lower one, never from a higher one.
STAGES = [
    ("errors", "version"),
    ("codes", "runtime"),
    ("util", "progress"),
    ("animation", "notebook"),
    ("result",),
    ("model",),
    ("derivation",),
    ("theory",),
    ("modelfile",),
    ("formulation",),
    ("codegen",),
    ("buildstep",),
    ("cache",),
    ("build",),
    ("libraries",),
    ("fmu",),
    ("solvers",),
    ("simulation",),
    ("sweep",),
    ("fitting",),
    ("api",),
    ("cli",),
    ("__main__", "__init__"),
]
RANK = {name: rank for rank, names in enumerate(STAGES) for name in names}


def module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__" and len(parts) > 1:
        parts = parts[:-1]
    return ".".join(parts)


def stage(module: str) -> str:
    return module.split(".")[0]


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def resolve(module: str, path: Path, node: ast.ImportFrom) -> list[tuple[str, str]]:
    """(imported module, imported name) pairs of a relative ``from`` import inside the package."""
    if node.level == 0:
        if not (node.module or "").startswith("lagcodegen"):
            return []
        base = node.module.split(".")[1:]
    else:
        pkg = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
        if path.name == "__init__.py" and module == "__init__":
            pkg = []
        up = node.level - 1
        base = (pkg[: len(pkg) - up] if up else pkg) + (node.module.split(".") if node.module else [])
    known = modules()
    out = []
    for alias in node.names:
        full = ".".join(base + [alias.name])
        if full in known:  # a submodule
            out.append((full, ""))
        else:
            out.append((".".join(base) or "__init__", alias.name))
    return out


def imports() -> list[tuple[str, str, str, int]]:
    """(importer, imported module, imported name, line) for every import within the package."""
    edges = []
    for module, path in modules().items():
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                for target, name in resolve(module, path, node):
                    edges.append((module, target, name, node.lineno))
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.startswith("lagcodegen."):
                        edges.append((module, alias.name[len("lagcodegen."):], "", node.lineno))
    return edges


def test_every_module_belongs_to_a_stage():
    unknown = sorted({stage(m) for m in modules()} - set(RANK))
    assert not unknown, f"modules outside the pipeline's stages: {unknown} (add them to STAGES)"


def test_imports_run_down_the_pipeline():
    wrong = []
    for src, dst, name, line in imports():
        if src == "__init__":
            continue  # the package's public surface re-exports every stage
        if dst == "__init__" and name:
            wrong.append(f"{src}:{line} imports {name!r} from the package itself")
            continue
        s, d = stage(src), stage(dst)
        if RANK[d] > RANK[s]:
            wrong.append(f"{src}:{line} (stage {s}) imports {dst} (higher stage {d})")
        elif RANK[d] == RANK[s] and s != d:
            wrong.append(f"{src}:{line} imports {dst}: two different modules of one stage")
    assert not wrong, "upward imports:\n" + "\n".join(wrong)


def test_no_import_circle():
    graph: dict[str, set[str]] = {}
    for src, dst, _, _ in imports():
        if src != dst:
            graph.setdefault(src, set()).add(dst)
    # a module imports its package's __init__ implicitly; that is not a circle of ours
    state: dict[str, int] = {}
    cycle: list[str] = []

    def visit(node: str, trail: list[str]) -> bool:
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if nxt in trail[:-1] and nxt == node:
                continue
            if state.get(nxt) == 1:
                cycle.extend(trail[trail.index(nxt):] + [nxt] if nxt in trail else [node, nxt])
                return True
            if state.get(nxt) is None and visit(nxt, trail + [nxt]):
                return True
        state[node] = 2
        return False

    for start in sorted(graph):
        if state.get(start) is None and visit(start, [start]):
            break
    assert not cycle, "import circle: " + " -> ".join(cycle)


def test_no_private_name_crosses_a_subpackage():
    crossing = []
    for src, dst, name, line in imports():
        private = name.startswith("_") and not name.startswith("__")
        private_module = any(part.startswith("_") and not part.startswith("__") for part in dst.split("."))
        if (private or private_module) and stage(src) != stage(dst):
            crossing.append(f"{src}:{line} imports {dst}.{name}".rstrip("."))
    assert not crossing, "private names used across subpackages:\n" + "\n".join(crossing)


@pytest.mark.parametrize("module", sorted(modules()))
def test_modules_stay_short_or_say_why(module):
    path = modules()[module]
    lines = path.read_text().count("\n")
    if lines > 600:
        doc = ast.get_docstring(ast.parse(path.read_text())) or ""
        assert "One job:" in doc, (f"{module} has {lines} lines: split it, or say in its docstring "
                                   f"('One job: ...') why it is one thing")


def test_every_subpackage_is_installed():
    """pyproject.toml lists the packages by name: a new subpackage left out would be missing
    from the installed wheel (the source tree's tests would not notice)."""
    import sys
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    listed = set(tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(("lagcodegen", *p.parent.relative_to(PACKAGE).parts)) for p in PACKAGE.rglob("__init__.py")}
    assert found <= listed, f"packages missing from pyproject.toml: {sorted(found - listed)}"


# ---------------------------------------------------------------------- public signatures, long modules
#: Parameters a public function or method may take at most.
MAX_PARAMETERS = 12
#: Public functions of other subsystems that are still wider (each to be cut, then removed from here).
WIDE_FOR_NOW: set = set()


def public_callables() -> dict[str, tuple]:
    """The public API, by qualified name: every function and class that ``lagcodegen/__init__.py``
    imports from a submodule by name, and every public function and class defined in a module it
    imports as a whole (``from .codegen import bundle``); of each class, its ``__init__`` and its
    methods without a leading underscore (static and class methods included). Values: (the
    function, whether it is bound to an instance or class, i.e. has a ``self``/``cls``)."""
    import importlib
    import inspect
    import types

    import lagcodegen

    found: dict[str, object] = {}

    def add_class(qual: str, cls) -> None:
        for name, member in vars(cls).items():
            if name.startswith("_") and name != "__init__":
                continue
            func = member.__func__ if isinstance(member, (staticmethod, classmethod)) else member
            if inspect.isfunction(func):
                found[f"{qual}.{name}"] = (member, not isinstance(member, staticmethod))

    def add(qual: str, obj) -> None:
        if inspect.isclass(obj):
            add_class(qual, obj)
        elif inspect.isfunction(obj):
            found[qual] = (obj, False)

    tree = ast.parse((PACKAGE / "__init__.py").read_text())
    for node in tree.body:
        if not (isinstance(node, ast.ImportFrom) and node.level == 1 and node.module):
            continue
        module = importlib.import_module(f"lagcodegen.{node.module}")
        for alias in node.names:
            if alias.name.startswith("_") or (alias.asname or "").startswith("_"):
                continue
            obj = getattr(module, alias.name, None)
            if obj is None or isinstance(obj, types.ModuleType):
                sub = obj if obj is not None else importlib.import_module(f"lagcodegen.{node.module}.{alias.name}")
                for name, member in vars(sub).items():
                    if not name.startswith("_") and getattr(member, "__module__", None) == sub.__name__:
                        add(f"{sub.__name__}.{name}", member)
            elif inspect.isclass(obj) or inspect.isfunction(obj):
                add(f"{obj.__module__}.{obj.__qualname__}", obj)
    assert lagcodegen  # the package imported as a whole first
    return found


def parameter_count(member, bound: bool) -> int | None:
    """The parameters of a function or method as a caller sees them: every name of its signature
    (``*args`` and ``**kwargs`` one each) except ``self``/``cls`` of a ``bound`` method; None for
    the ``__init__`` a dataclass generates (a record's fields, each named and defaulted, not a call
    that flattens options)."""
    import inspect
    func = member.__func__ if isinstance(member, (staticmethod, classmethod)) else member
    if func.__name__ == "__init__" and func.__code__.co_filename.startswith("<"):  # made by @dataclass
        return None
    params = list(inspect.signature(func).parameters)
    return len(params) - (1 if bound and params else 0)


def too_wide(callables: dict) -> list[str]:
    out = []
    for qual, (member, bound) in sorted(callables.items()):
        count = parameter_count(member, bound)
        if count is not None and count > MAX_PARAMETERS and qual not in WIDE_FOR_NOW:
            out.append(f"{qual}: {count} parameters")
    return out


def test_public_functions_take_at_most_twelve_parameters():
    """The rule: a function or method of the public API (see :func:`public_callables`: what
    ``lagcodegen/__init__.py`` imports by name, the public functions and classes of the modules it
    imports whole, and of every such class its ``__init__`` and public methods) takes at most
    MAX_PARAMETERS = 12 parameters, counting every name of its signature (``*args`` and
    ``**kwargs`` one each) except ``self``/``cls``; a dataclass's generated ``__init__`` (a record's
    fields) does not count. Options that belong together go into an object (a solver family,
    a Scene), not into more keywords."""
    callables = public_callables()
    assert "lagcodegen.simulation.ode.CompiledModel.simulate" in callables
    assert "lagcodegen.api.compile_constrained" in callables
    wide = too_wide(callables)
    assert not wide, "public functions with more than 12 parameters:\n" + "\n".join(wide)


def test_the_parameter_rule_catches_a_wide_function():
    def wide(a, b, c, d, e, f, g, h, i, j, k, *, m=0, **rest):  # 13
        return a

    class Face:
        def simulate(self, t, q0, v0, *, y0, z0, params, solver, rtol, atol, events, raise_on_error, **options):
            return t  # 12: allowed

    assert too_wide({"x.wide": (wide, False), "x.Face.simulate": (Face.__dict__["simulate"], True)}) == \
        ["x.wide: 13 parameters"]
    assert too_wide({"x.Face.simulate": (Face.__dict__["simulate"], False)}) == ["x.Face.simulate: 13 parameters"]


#: Functions anywhere in the package still wider than MAX_PARAMETERS, with why (each to be cut,
#: then removed from here): keywords a test or the public API pins.
WIDE_INSIDE: dict = {}


def wide_inside(limit: int = MAX_PARAMETERS) -> list[str]:
    """Every function or method of the package (internal ones too: the drivers, steppers and
    ensembles take records, :mod:`lagcodegen.solvers.request`, not long keyword lists) taking more
    than ``limit`` parameters, ``*args`` and ``**kwargs`` one each, ``self``/``cls`` not counted:
    "path:name: count"."""
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                a = node.args
                count = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + bool(a.vararg) + bool(a.kwarg)
                if a.args and a.args[0].arg in ("self", "cls"):
                    count -= 1
                if count > limit:
                    out.append(f"{path.relative_to(PACKAGE.parent)}:{node.name}: {count}")
    return out


def test_no_function_inside_takes_more_than_twelve_parameters():
    wide = [w for w in wide_inside() if w.rsplit(":", 1)[0] not in WIDE_INSIDE]
    assert not wide, "functions with more than 12 parameters (group them into a record):\n" + "\n".join(wide)
    assert len(wide_inside()) == len(WIDE_INSIDE), "an entry of WIDE_INSIDE is no longer wide: remove it"


def first_sentence(doc: str) -> str:
    """The first sentence of a docstring's first paragraph (up to a period followed by a space or
    the paragraph's end), or "" when the first paragraph has no period."""
    import re
    para = " ".join(doc.strip().split("\n\n")[0].split())
    match = re.search(r"\.(\s|$)", para)
    return para[: match.start() + 1] if match else ""


def job_problem(text: str, limit: int = 500) -> str | None:
    """Why a module's source ``text`` breaks the rule, or None: a module over ``limit`` lines must
    open with a docstring whose first sentence says what the module does (one statement of 6 to
    80 words ending with a period)."""
    lines = text.count("\n")
    if lines <= limit:
        return None
    doc = ast.get_docstring(ast.parse(text)) or ""
    sentence = first_sentence(doc)
    words = len(sentence.split())
    if not doc:
        return f"{lines} lines and no docstring"
    if not 6 <= words <= 80:
        return f"{lines} lines and the docstring's first sentence has {words} words: {sentence[:80]!r}"
    return None


@pytest.mark.parametrize("module", sorted(modules()))
def test_long_modules_open_with_their_job(module):
    """A module over 500 lines opens with a docstring whose first sentence says what it does."""
    problem = job_problem(modules()[module].read_text())
    assert problem is None, f"{module}: {problem}: split it or state its one job in its first sentence"


def test_the_job_rule_catches_a_long_module_without_one():
    body = "x = 1\n" * 501
    assert job_problem(body) == "501 lines and no docstring"
    assert "first sentence has 2 words" in job_problem('"""Various helpers."""\n' + body)
    assert job_problem('"""Loading a model file: the TOML document, section by section, into a Model."""\n'
                       + body) is None
    assert job_problem('"""Short."""\n' + "x = 1\n" * 10) is None


# ----------------------------------------------------------------------------- backends as peers
def backend_files() -> dict[str, set[Path]]:
    """The files of each registered language backend (lagcodegen.codegen.languages.BACKENDS): the
    module of its backend class and of its printer class."""
    from lagcodegen.codegen.languages import BACKENDS
    import inspect
    out: dict[str, set[Path]] = {}
    for name, cls in BACKENDS.items():
        files = {Path(inspect.getfile(cls))}
        printer = getattr(cls, "printer", None)
        if printer is not None:
            files.add(Path(inspect.getfile(printer)))
        module = inspect.getmodule(cls)
        for obj in vars(module).values():  # the printer class the backend module uses
            if inspect.isclass(obj) and obj.__name__.endswith("Printer") and obj.__module__.startswith("lagcodegen"):
                files.add(Path(inspect.getfile(obj)))
        out[name] = files
    return out


def text_parsing_problems(tree: ast.AST, others: set[str]) -> list[str]:
    """Why a backend module's ``tree`` parses printed text or leans on another backend: an import of
    another backend's module (``others``: their stems), ``re.sub/subn/findall/finditer/search`` or a
    ``str.replace`` (only ``dataclasses.replace``, a record, is allowed)."""
    problems = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level >= 1:
            names = {(node.module or "").split(".")[-1]} | {a.name for a in node.names}
            if names & others:
                problems.append(f"imports another backend's module {sorted(names & others)}")
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            owner = node.func.value
            if node.func.attr in ("sub", "subn", "findall", "finditer", "search") and \
                    isinstance(owner, ast.Name) and owner.id == "re":
                problems.append(f"re.{node.func.attr} (line {node.lineno})")
            if node.func.attr == "replace" and not (isinstance(owner, ast.Name) and owner.id == "dataclasses"):
                problems.append(f"str.replace (line {node.lineno})")
    return problems


def test_backends_are_peers_that_never_parse_printed_text():
    """No text-parsing step between backends: each registered backend prints the operation tree
    itself (no import of another backend, no regular expression or str.replace on printed text)."""
    files = backend_files()
    assert set(files) >= {"c", "fortran"}
    for lang, paths in files.items():
        others = {p.stem for k, ps in files.items() if k != lang for p in ps} - {p.stem for p in paths}
        for path in paths:
            problems = text_parsing_problems(ast.parse(path.read_text()), others)
            assert not problems, f"backend {lang!r}, {path.name}: {problems}"


def test_the_peer_rule_catches_text_parsing():
    code = "from .c import c_expr\nimport re\ny = re.sub('x', 'y', c_expr(e)).replace('a', 'b')\n"
    problems = text_parsing_problems(ast.parse(code), {"c"})
    assert len(problems) == 3 and "another backend" in problems[0]
    assert text_parsing_problems(ast.parse("import dataclasses\nr = dataclasses.replace(r, a=1)\n"), {"c"}) == []
