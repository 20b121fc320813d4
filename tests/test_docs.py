"""The code blocks of the documentation pages run: each page's ```python blocks, in order, in
one namespace, in an empty folder (the pictures they write are checked to exist)."""

import re
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"
PAGES = sorted(p for p in DOCS.rglob("*.md") if re.search(r"^```python$", p.read_text(), re.M))


def blocks(page: Path) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```$", page.read_text(encoding="utf-8"), re.M | re.S)


def test_pages_with_code_are_found():
    names = [p.relative_to(DOCS).as_posix() for p in PAGES]
    for page in ("pictures-and-notebooks.md", "getting-started.md", "howto/constraints.md", "howto/routhian.md",
                 "howto/solvers.md", "howto/ensembles.md", "howto/bundles.md", "howto/rigid-bodies.md",
                 "howto/fmu.md", "howto/events.md", "howto/integrator.md", "howto/sensitivities.md"):
        assert page in names


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(DOCS).as_posix())
def test_code_blocks_run(page, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    code = blocks(page)
    for i, block in enumerate(code):
        exec(compile(block, f"{page.name}[block {i}]", "exec"), namespace)  # noqa: S102 - our own docs
    text = "\n".join(code)
    written = re.findall(r'"([\w.-]+\.(?:gif|html|png|csv|fmu))"', text)
    assert all((tmp_path / name).stat().st_size > 0 for name in written)
    if page.name in ("pictures-and-notebooks.md", "getting-started.md"):
        assert any(name.endswith((".gif", ".html")) for name in written)


def test_getting_started_prints_what_its_comments_say(tmp_path, monkeypatch):
    """Each `print(...)  # text` of the getting-started page prints exactly that text (it said a
    list where res.outputs, a dict of arrays, printed the arrays)."""
    import contextlib
    import io
    monkeypatch.chdir(tmp_path)
    page = DOCS / "getting-started.md"
    code = blocks(page)
    out = io.StringIO()
    namespace: dict = {}
    with contextlib.redirect_stdout(out):
        for i, block in enumerate(code):
            exec(compile(block, f"{page.name}[block {i}]", "exec"), namespace)  # noqa: S102 - our own docs
    printed = out.getvalue().splitlines()
    said = re.findall(r"^\s*print\(.*\)\s+# (.*)$", "\n".join(code), re.M)
    assert len(said) >= 3
    for text in said:
        assert text.strip() in printed, (text, printed)
