"""The documentation site's sources are complete (its build itself, `mkdocs build --strict`, runs
in .ci/run after the tests): every public name of lagcodegen has a docstring and an entry in an
API page, every page is in the navigation, and no page names a machine's paths."""

import inspect
import re
import types
from pathlib import Path

import lagcodegen

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: Modules documented as a whole in the API pages (their public members are lagcodegen's too).
DOCUMENTED_MODULES = ("systems", "progress", "modelfile", "urdf")


def public_names() -> list[str]:
    """lagcodegen's public names: its classes, functions and constants (not its subpackages,
    except the modules documented as a whole)."""
    out = []
    for name, value in vars(lagcodegen).items():
        if name.startswith("_") or name == "annotations":
            continue
        if isinstance(value, types.ModuleType) and name not in DOCUMENTED_MODULES:
            continue
        out.append(name)
    return sorted(out)


def documented() -> set[str]:
    """The names the API pages render (``::: lagcodegen.NAME`` directives)."""
    text = "\n".join(p.read_text(encoding="utf-8") for p in (DOCS / "api").glob("*.md"))
    return set(re.findall(r"^::: lagcodegen\.(\w+)\s*$", text, re.M))


def docstring(name: str) -> str:
    value = getattr(lagcodegen, name)
    if inspect.isclass(value) or inspect.isroutine(value) or isinstance(value, types.ModuleType):
        return inspect.getdoc(value) or ""
    # a constant: the ``#:`` comment above its assignment in the module that defines it
    for module in (lagcodegen.api, lagcodegen):
        lines = inspect.getsource(module).splitlines()
        for i, line in enumerate(lines):
            if line.startswith(f"{name} ="):
                comment = []
                while i > 0 and lines[i - 1].startswith("#:"):
                    i -= 1
                    comment.insert(0, lines[i][2:].strip())
                return " ".join(comment)
    return ""


def test_every_public_name_has_a_docstring():
    names = public_names()
    assert {"Model", "compile_model", "Result", "ConstrainedSystem", "linearize", "export_fmu", "urdf",
            "write_bundle", "CompiledModel"} <= set(names)
    missing = [n for n in names if len(docstring(n).split()) < 3]
    assert not missing, f"public names without a docstring: {missing}"


def test_every_public_name_is_in_an_api_page():
    missing = sorted(set(public_names()) - documented())
    assert not missing, f"public names in no page of docs/api/ (add '::: lagcodegen.NAME'): {missing}"
    unknown = sorted(documented() - set(public_names()))
    assert not unknown, f"API pages render names lagcodegen does not export: {unknown}"


def test_documented_module_members_exist():
    text = (DOCS / "api" / "modelfiles.md").read_text(encoding="utf-8")
    for module, block in re.findall(r"^::: lagcodegen\.(\w+)\n((?:    .*\n)+)", text, re.M):
        for member in re.findall(r"^        - (\w+)$", block, re.M):
            assert inspect.getdoc(getattr(getattr(lagcodegen, module), member)), f"{module}.{member}"


def test_every_page_is_in_the_navigation():
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    generated = {"gallery.md", "command-line.md"}  # made by tools/docs_hooks.py at build time
    pages = {p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md")}
    listed = set(re.findall(r":\s*([\w/.-]+\.md)\s*$", nav, re.M))
    assert pages | generated == listed
    assert not pages & generated


def test_pages_name_no_machine_paths():
    for page in [*DOCS.rglob("*.md"), ROOT / "mkdocs.yml"]:
        text = page.read_text(encoding="utf-8")
        found = re.findall(r"(?:/work/|/tmp/|/root/|/home/\w+|[A-Z]:\\\\)", text)
        assert not found, f"{page.name}: {found}"


def test_the_gallery_page_shows_every_example_and_its_pictures():
    """tools/gallery.py's page (the pictures themselves are drawn by the site's build in .ci/run)."""
    import sys
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import gallery
    finally:
        sys.path.remove(str(ROOT / "tools"))
    examples = sorted(p for p in (ROOT / "examples").iterdir() if p.suffix in (".toml", ".urdf", ".py"))
    entries = [gallery.Entry(p.name, gallery._title_of_script(p) if p.suffix == ".py" else
                             gallery._title_of_model_file(p), f"run {p.name}", [f"{p.stem}.png"]) for p in examples]
    assert all(len(e.title.split()) >= 4 and "<!--" not in e.title and "#" not in e.title for e in entries)
    text = gallery.page(entries)
    for e in entries:
        assert f"### {e.name}\n\n{e.title}\n" in text and f"(gallery/{e.pictures[0]})" in text
