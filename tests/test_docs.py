"""The code blocks of the documentation pages run: each page's ```python blocks, in order, in
one namespace, in an empty folder (the files they write are checked to exist)."""

import re
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"
PAGES = sorted(p for p in DOCS.glob("*.md") if re.search(r"^```python$", p.read_text(), re.M))


def blocks(page: Path) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```$", page.read_text(encoding="utf-8"), re.M | re.S)


def test_pages_with_code_are_found():
    assert "pictures-and-notebooks.md" in [p.name for p in PAGES]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_code_blocks_run(page, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for i, code in enumerate(blocks(page)):
        exec(compile(code, f"{page.name}[block {i}]", "exec"), namespace)  # noqa: S102 - our own docs
    written = re.findall(r'"([\w.-]+\.(?:gif|html|png))"', page.read_text())
    assert written and all((tmp_path / name).stat().st_size > 0 for name in written)
