"""lagcodegen.util: files written together (staged_outputs)."""

import pytest

from lagcodegen.errors import LagcodegenError
from lagcodegen.util import staged_outputs


def test_staged_outputs_appear_together(tmp_path):
    a, b = tmp_path / "x" / "a.csv", tmp_path / "b.png"
    with staged_outputs([a, None, b]) as staged:
        assert set(staged) == {a, b} and staged[a].suffix == ".csv" and staged[b].suffix == ".png"
        staged[a].write_text("a")
        staged[b].write_text("b")
        assert not a.exists() and not b.exists()
    assert a.read_text() == "a" and b.read_text() == "b"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.png", "x"]
    assert [p.name for p in a.parent.iterdir()] == ["a.csv"]


def test_staged_outputs_leave_nothing_on_interrupt(tmp_path):
    a, b = tmp_path / "new" / "sub" / "a.csv", tmp_path / "b.png"
    b.write_text("earlier")
    with pytest.raises(KeyboardInterrupt):
        with staged_outputs([a, b]) as staged:
            staged[a].write_text("a")
            raise KeyboardInterrupt
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.png"] and b.read_text() == "earlier"


def test_staged_outputs_refuse_one_file_twice(tmp_path):
    with pytest.raises(LagcodegenError, match="must differ"):
        with staged_outputs([tmp_path / "a.csv", tmp_path / "." / "a.csv"]):
            pass
