"""The model-file schema (lagcodegen.modelfile.schema) is what the loader validates against, and
docs/model-files.md is generated from it: regenerating the reference must give the committed
file, and every table's allowed and required keys in the loader's messages are the schema's."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

from lagcodegen.modelfile import ModelFileError, loads_model
from lagcodegen.modelfile import schema
from lagcodegen.modelfile.document import SimulationSettings

ROOT = Path(__file__).resolve().parents[2]

#: One valid file using every table; each block is the text of one table (its key lines).
BLOCKS = {
    "model": '[model]\nname = "every"\ncoordinates = ["x", "y", "phi"]\n',
    "parameters": "[parameters]\nk = 2.0\n",
    "inputs": "[inputs]\nu = 0.0\n",
    "units": '[units]\nx = "m"\nk = "N/m"\nu = "N"\n',
    "points": '[[points]]\nname = "anchor"\nposition = [0, 0]\n',
    "particles": '[[particles]]\nname = "bob"\nmass = 1\nposition = ["x", "y"]\n',
    "planar_bodies": '[[planar_bodies]]\nname = "plate"\nmass = 1\ninertia = 0.1\nposition = ["x", 0]\n'
                     'angle = "phi"\n',
    "rigid_bodies": '[[rigid_bodies]]\nname = "top"\nmass = 1\ninertia = [1, 1, 2]\nposition = [0, 0, "y"]\n'
                    'orientation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\n',
    "gravity": '[gravity]\ng = 9.81\n',
    "springs": '[[springs]]\na = "bob"\nb = "anchor"\nk = "k"\nrest_length = 0.5\nlabel = "s"\n',
    "dampers": '[[dampers]]\npoint = "bob"\nc = 0.1\nb = "anchor"\nlabel = "d"\n',
    "forces": '[[forces]]\npoint = "bob"\nvector = ["0", "-x_dot"]\nlabel = "f"\n',
    "generalized_forces": '[[generalized_forces]]\ncoordinate = "phi"\nexpr = "-phi_dot"\nlabel = "q"\n',
    "energy": '[energy]\npotential = "k*phi**2/2"\n',
    "outputs": '[outputs]\nr2 = "x**2 + y**2"\n',
    "constraints": '[constraints]\nholonomic = ["x - phi"]\nnonholonomic = [{ A = [0, 1, 0], A0 = 0 }]\n'
                   'integrable = "allow"\ninequalities = ["10 - x"]\n',
    "events": '[[events]]\nname = "far"\nexpr = "x - 5"\ndirection = 1\nterminal = true\n',
    "simulation": '[simulation]\nt_end = 1.0\nn_out = 11\n',
}


def document(blocks=BLOCKS) -> str:
    return "\n".join(blocks[name] for name in schema.TOP_LEVEL)


def test_the_committed_reference_is_the_generated_one():
    committed = (ROOT / "docs" / "model-files.md").read_text(encoding="utf-8")
    assert committed == schema.reference() + "\n", "run python tools/model_file_reference.py"
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "model_file_reference.py"), "--check"],
                          capture_output=True, text=True, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    assert proc.returncode == 0, proc.stderr


def test_the_reference_names_every_table_and_key():
    text = schema.reference()
    for t in schema.SCHEMA + schema.NESTED:
        assert t.name.split(".")[-1] in text
        for k in t.keys:
            assert f"| `{k.name}` |" in text
    # defaults come from the settings the loader fills in
    s = SimulationSettings()
    assert f"| `t_end` | constant | no | {s.t_end:g} |" in text
    assert f"| `method` | string | no | \"{s.method}\" |" in text


def test_the_schema_covers_the_whole_format():
    mf = loads_model(document())
    assert mf.constrained is not None and [e.name for e in mf.events] == ["far"]
    assert set(BLOCKS) == set(schema.TOP_LEVEL)
    with pytest.raises(ModelFileError) as err:
        loads_model(document() + "\n[bodies]\nx = 1\n")
    allowed = re.search(r"allowed: ([^)]*)\)", str(err.value)).group(1).split(", ")
    assert allowed == list(schema.TOP_LEVEL)


@pytest.mark.parametrize("table", [t for t in schema.SCHEMA if t.kind != "map"], ids=lambda t: t.name)
def test_the_loader_allows_and_requires_the_schemas_keys(table):
    blocks = dict(BLOCKS)
    blocks[table.name] = BLOCKS[table.name] + "zzz_unknown = 1\n"
    with pytest.raises(ModelFileError) as err:
        loads_model(document(blocks))
    msg = str(err.value)
    assert "unknown key 'zzz_unknown'" in msg
    assert re.search(r"allowed: ([^)]*)\)", msg).group(1).split(", ") == table.required_keys() + table.optional_keys()
    for key in table.required_keys():
        blocks = dict(BLOCKS)
        blocks[table.name] = "".join(line + "\n" for line in BLOCKS[table.name].splitlines()
                                     if not line.startswith(f"{key} ="))
        with pytest.raises(ModelFileError, match=f"missing required key '{key}'"):
            loads_model(document(blocks))


def test_nested_nonholonomic_entries_follow_the_schema():
    nested = schema.table("constraints.nonholonomic")
    blocks = dict(BLOCKS)
    blocks["constraints"] = BLOCKS["constraints"].replace("A0 = 0 }", "A0 = 0, zzz_unknown = 1 }")
    with pytest.raises(ModelFileError) as err:
        loads_model(document(blocks))
    assert re.search(r"allowed: ([^)]*)\)", str(err.value)).group(1).split(", ") == nested.optional_keys()
