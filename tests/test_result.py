"""Result files: written through a unique temporary file beside the target, never a planted one."""


import numpy as np
import pytest

from lagcodegen.result import Result


def small_result():
    t = np.linspace(0.0, 1.0, 11)
    return Result(t=t, y=np.column_stack([np.sin(t), np.cos(t)]), state_names=["x", "x_dot"],
                  outputs={"energy": np.ones_like(t)}, n_coordinates=1)


def test_plot_never_writes_through_a_planted_symlink(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    (tmp_path / ".plot.png.tmp.png").symlink_to(victim)  # the name the plot once wrote through
    target = tmp_path / "plot.png"
    assert small_result().plot(target) == target
    assert victim.read_text() == "precious\n"
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".plot.png.tmp.png", "plot.png", "victim.txt"]
    assert oct(target.stat().st_mode & 0o777) == oct(0o644)


def test_failed_plot_leaves_neither_target_nor_temporary(tmp_path, monkeypatch):
    import matplotlib.figure

    def fail(self, *args, **kwargs):
        raise OSError("disk full")
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", fail)
    target = tmp_path / "plot.png"
    with pytest.raises(OSError, match="disk full"):
        small_result().plot(target)
    assert not list(tmp_path.iterdir())


def test_plot_replaces_an_existing_file_whole(tmp_path):
    target = tmp_path / "plot.png"
    target.write_text("old")
    small_result().plot(target, what=["x", "energy"])
    assert target.read_bytes()[:4] == b"\x89PNG"
    assert [p.name for p in tmp_path.iterdir()] == ["plot.png"]
