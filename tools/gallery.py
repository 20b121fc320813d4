"""Draw the examples gallery: every example script in examples/ is run in an empty folder and the
pictures it writes are collected; every model file (TOML, URDF) in examples/ is simulated as
`lagcodegen simulate` would and drawn (its plot, and an animation of the mechanism).

    python tools/gallery.py OUT        # OUT/gallery.md and the pictures in OUT/gallery/

The documentation build calls :func:`draw` (tools/docs_hooks.py), so the pictures are made from
the examples of the tree being documented and never committed. An example that fails stops the
build with its output.
"""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
#: Seconds an example script may take.
TIMEOUT = 600


@dataclass
class Entry:
    """One example: its file, its first docstring line, how to run it, the pictures it made."""

    name: str
    title: str
    command: str
    pictures: list[str] = field(default_factory=list)


def _title_of_script(path: Path) -> str:
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or path.stem
    return " ".join(doc.split("\n\n")[0].split())


def _title_of_model_file(path: Path) -> str:
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".urdf":  # its first XML comment
        start, end = text.find("<!--"), text.find("-->")
        comment = text[start + 4:end] if 0 <= start < end else path.stem
        return " ".join(comment.split()).split(". ")[0].rstrip(".") + "."  # its first sentence
    lines = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("#"):
            break
        lines.append(line.lstrip("# ").strip())
    return " ".join(lines) or path.stem


def _run_script(script: Path, pictures: Path) -> list[str]:
    """Run ``script`` in an empty folder; move the PNG and GIF files it wrote into ``pictures``."""
    with tempfile.TemporaryDirectory(prefix="lcg_gallery_") as work:
        env = dict(os.environ, MPLBACKEND="Agg")
        proc = subprocess.run([sys.executable, str(script)], cwd=work, env=env, capture_output=True,
                              text=True, timeout=TIMEOUT)
        if proc.returncode != 0:
            raise RuntimeError(f"examples/{script.name} failed (exit {proc.returncode}):\n"
                               f"{proc.stdout[-2000:]}{proc.stderr[-4000:]}")
        made = []
        for picture in sorted(Path(work).rglob("*")):
            if picture.suffix in (".png", ".gif"):
                name = f"{script.stem}--{picture.name}"
                shutil.move(str(picture), pictures / name)
                made.append(name)
        return made


def _draw_model_file(path: Path, pictures: Path) -> list[str]:
    """Simulate a model file as ``lagcodegen simulate`` does; save its plot and an animation."""
    import lagcodegen as lcg

    mf = lcg.modelfile.load_model_path(path)
    res = mf.simulate(lcg.compile_file(mf))
    plot = f"{path.stem}.png"
    res.plot(pictures / plot)
    made = [plot]
    try:
        animation = f"{path.stem}.gif"
        res.animate(pictures / animation, frames=40, fps=10)
        made.append(animation)
    except lcg.LagcodegenError:
        pass  # a result without a drawing (no points or bodies to draw): the plot only
    return made


def draw(out: Path) -> list[Entry]:
    """Run every example into ``out`` (pictures) and return the entries of the gallery page."""
    out.mkdir(parents=True, exist_ok=True)
    entries = []
    for path in sorted([*EXAMPLES.glob("*.toml"), *EXAMPLES.glob("*.urdf")]):
        entries.append(Entry(path.name, _title_of_model_file(path),
                             f"lagcodegen simulate examples/{path.name} -o out/{path.stem}.csv "
                             f"--plot out/{path.stem}.png", _draw_model_file(path, out)))
    for path in sorted(EXAMPLES.glob("*.py")):
        entries.append(Entry(path.name, _title_of_script(path), f"python examples/{path.name}",
                             _run_script(path, out)))
    return entries


def page(entries: list[Entry], folder: str = "gallery") -> str:
    """The gallery page (Markdown) of ``entries``, the pictures under ``folder``/."""
    parts = ["# Gallery", "",
             "Every picture on this page was drawn while this site was built, by the examples in the",
             "`examples/` folder of the source tree (`python tools/gallery.py OUT` draws them again).",
             "Model files are simulated as `lagcodegen simulate` does and animated with `res.animate`;",
             "the scripts run as they are and write their own pictures.", ""]
    for kind, suffix in (("Model files", ".toml"), ("Robots (URDF)", ".urdf"), ("Scripts", ".py")):
        parts += [f"## {kind}", ""]
        for e in entries:
            if not e.name.endswith(suffix):
                continue
            parts += [f"### {e.name}", "", e.title, "", "```sh", e.command, "```", ""]
            parts += [f"![{e.name}: {p}]({folder}/{p})" for p in e.pictures]
            parts += [""] if e.pictures else ["(no picture: it prints its results)", ""]
    return "\n".join(parts)


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print(__doc__, file=sys.stderr)
        return 2
    out = Path(argv[0])
    entries = draw(out / "gallery")
    (out / "gallery.md").write_text(page(entries), encoding="utf-8")
    print(f"wrote {out / 'gallery.md'} and {sum(len(e.pictures) for e in entries)} pictures")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
