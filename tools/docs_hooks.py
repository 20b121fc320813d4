"""MkDocs hooks of the documentation site (mkdocs.yml): pages made from the code at build time,
so that they cannot drift from it.

* ``gallery.md`` and its pictures: the examples run and drawn (tools/gallery.py; with
  ``LAGCODEGEN_GALLERY=DIR`` set, those ``python tools/gallery.py DIR`` drew before);
* ``command-line.md``: the ``--help`` text of ``lagcodegen`` and of each of its commands.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

from mkdocs.structure.files import File, Files

sys.path.insert(0, str(Path(__file__).resolve().parent))

import gallery  # noqa: E402  (tools/gallery.py)

_WORK: tempfile.TemporaryDirectory | None = None


def command_line_page() -> str:
    """The command-line reference: the help of ``lagcodegen`` and of each command, as printed."""
    from lagcodegen.cli import COMMANDS, parser

    os.environ["COLUMNS"] = "100"  # argparse wraps the help to this width
    ap = parser()
    sub = next(a for a in ap._actions if a.dest == "command")  # the subcommands' parsers
    parts = ["# Command line", "",
             "`lagcodegen` (or `python -m lagcodegen`) runs one command on a model file: a TOML file",
             "(see the [model-file reference](model-files.md)), a URDF robot, or `FILE.py:FUNCTION`.",
             "This page is the `--help` of each command, as the installed program prints it.", "",
             "## lagcodegen", "", "```text", ap.format_help().rstrip(), "```", ""]
    for command in COMMANDS:
        name = command.__name__.rsplit(".", 1)[-1]
        parts += [f"## lagcodegen {name}", "", "```text", sub.choices[name].format_help().rstrip(), "```", ""]
    return "\n".join(parts)


def on_files(files: Files, config) -> Files:
    """Add the generated pages and pictures to the site's files."""
    global _WORK
    drawn = os.environ.get("LAGCODEGEN_GALLERY")
    if drawn:  # drawn before by `python tools/gallery.py DIR`: DIR/gallery.md and DIR/gallery/
        pictures = Path(drawn) / "gallery"
        page = (Path(drawn) / "gallery.md").read_text(encoding="utf-8")
    else:
        _WORK = tempfile.TemporaryDirectory(prefix="lcg_docs_")
        pictures = Path(_WORK.name) / "gallery"
        page = gallery.page(gallery.draw(pictures))
    files.append(File.generated(config, "gallery.md", content=page))
    for picture in sorted(pictures.iterdir()):
        files.append(File.generated(config, f"gallery/{picture.name}", abs_src_path=str(picture)))
    files.append(File.generated(config, "command-line.md", content=command_line_page()))
    return files


def on_post_build(config) -> None:
    """Remove the pictures' temporary folder once the site is written."""
    global _WORK
    if _WORK is not None:
        _WORK.cleanup()
        _WORK = None
