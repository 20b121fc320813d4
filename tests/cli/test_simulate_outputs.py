"""`lagcodegen simulate`'s output files appear together when all are complete: Ctrl-C (or a
failure) while one of them is written leaves none, as the README says."""

from pathlib import Path

import pytest

from lagcodegen.cli import main
from lagcodegen.result import Result

PENDULUM = Path(__file__).resolve().parents[2] / "examples" / "pendulum.toml"


@pytest.mark.parametrize("existing", [False, True])
def test_ctrl_c_while_animating_leaves_no_output(tmp_path, monkeypatch, existing):
    def interrupted(self, path, **kwargs):
        Path(path).write_bytes(b"GIF89a half a movie")
        raise KeyboardInterrupt
    monkeypatch.setattr(Result, "animate", interrupted)
    out = tmp_path / "out" if not existing else tmp_path
    if existing:  # the files of an earlier run stay as they were
        for name in ("r.csv", "p.png", "m.gif"):
            (out / name).write_text("earlier\n")
    argv = ["simulate", str(PENDULUM), "-o", str(out / "r.csv"), "--plot", str(out / "p.png"), "--animate",
            str(out / "m.gif"), "--t-end", "0.5", "-q"]
    assert main(argv) == 130
    if existing:
        assert sorted(p.name for p in tmp_path.iterdir()) == ["m.gif", "p.png", "r.csv"]
        assert all((out / name).read_text() == "earlier\n" for name in ("r.csv", "p.png", "m.gif"))
    else:
        assert list(tmp_path.iterdir()) == []  # not even the folder made for them


def test_the_outputs_are_written_when_all_are_complete(tmp_path, capsys):
    out = tmp_path / "deep" / "er"
    argv = ["simulate", str(PENDULUM), "-o", str(out / "r.csv"), "--plot", str(out / "p.png"), "--t-end", "0.5"]
    assert main(argv) == 0
    assert sorted(p.name for p in out.iterdir()) == ["p.png", "r.csv"]  # no temporary file left
    err = capsys.readouterr().err
    assert f"wrote {out / 'r.csv'}" in err and f"wrote {out / 'p.png'}" in err
