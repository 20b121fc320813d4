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
    ("util", "progress"),
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
    ("solvers",),
    ("sweep",),
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
