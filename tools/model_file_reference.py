"""Write docs/model-files.md, the model-file reference, from the loader's own schema
(lagcodegen/modelfile/schema.py: every table, key, type, default and meaning).

    python tools/model_file_reference.py            # rewrite docs/model-files.md
    python tools/model_file_reference.py --check    # exit 1 if the committed file differs

tests/modelfile/test_schema.py runs the check, so the reference cannot drift from the code.
"""

from __future__ import annotations

import sys
from pathlib import Path

TARGET = Path(__file__).resolve().parents[1] / "docs" / "model-files.md"


def main(argv: list[str]) -> int:
    from lagcodegen.modelfile.schema import reference

    text = reference() + "\n"
    if "--check" in argv:
        if not TARGET.exists() or TARGET.read_text(encoding="utf-8") != text:
            print(f"{TARGET} is out of date: run python tools/model_file_reference.py", file=sys.stderr)
            return 1
        return 0
    TARGET.parent.mkdir(parents=True, exist_ok=True)
    TARGET.write_text(text, encoding="utf-8")
    print(f"wrote {TARGET}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
