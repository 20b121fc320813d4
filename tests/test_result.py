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


# ---------------------------------------------------------------------- CSV
def recording_writer(monkeypatch, fail_at: int | None = None):
    """Record the sizes of the writes of result files (through lagcodegen.result.atomic_binary);
    with ``fail_at``, that write raises KeyboardInterrupt (as Ctrl-C between chunks)."""
    import contextlib

    import lagcodegen.result as result_module
    real = result_module.atomic_binary
    sizes: list[int] = []

    @contextlib.contextmanager
    def recording(path):
        with real(path) as fh:
            class Recorded:
                def write(self, data):
                    if fail_at is not None and len(sizes) == fail_at:
                        raise KeyboardInterrupt
                    sizes.append(len(data))
                    return fh.write(data)
            yield Recorded()
    monkeypatch.setattr(result_module, "atomic_binary", recording)
    return sizes


def test_csv_values_read_back_as_the_same_doubles(tmp_path):
    values = np.array([0.0, -0.0, 0.1, 1 / 3, 1.0, -2.5e-300, 5e-324, 1.7976931348623157e308, 123456789.123456789,
                       np.nan, np.inf, -np.inf])
    t = np.arange(float(values.size))
    res = Result(t=t, y=np.column_stack([values, values[::-1]]), state_names=["x", "x_dot"],
                 outputs={"energy": -values}, n_coordinates=1)
    path = res.save(tmp_path / "r.csv")
    lines = path.read_text().splitlines()
    assert lines[0] == "t,x,x_dot,energy" and len(lines) == values.size + 1
    back = np.array([[float(x) for x in line.split(",")] for line in lines[1:]])
    expected = np.column_stack([t, values, values[::-1], -values])
    nan = np.isnan(expected)
    assert np.array_equal(np.isnan(back), nan)  # nan as nan (its sign is not kept, as before)
    assert np.array_equal(back[~nan].view(np.int64), expected[~nan].view(np.int64))  # bit for bit, -0.0 too
    assert np.array_equal(np.loadtxt(path, delimiter=",", skiprows=1), expected, equal_nan=True)


def test_csv_is_written_in_chunks_of_bounded_size(tmp_path, monkeypatch):
    import lagcodegen.result as result_module
    monkeypatch.setattr(result_module, "CSV_CHUNK_VALUES", 30)  # 10 rows of 3 columns a chunk
    sizes = recording_writer(monkeypatch)
    t = np.linspace(0.0, 1.0, 101)
    res = Result(t=t, y=np.column_stack([np.sin(t), np.cos(t)]), state_names=["x", "x_dot"], outputs={},
                 n_coordinates=1)
    path = res.save(tmp_path / "r.csv")
    assert len(sizes) == 1 + 11  # the header, then 11 chunks: never the whole text in one piece
    assert max(sizes) < path.stat().st_size / 5
    assert np.array_equal(np.loadtxt(path, delimiter=",", skiprows=1), np.column_stack([t, res.y]))


def test_ctrl_c_between_csv_chunks_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    import lagcodegen.result as result_module
    monkeypatch.setattr(result_module, "CSV_CHUNK_VALUES", 30)
    recording_writer(monkeypatch, fail_at=3)  # Ctrl-C after the header and two chunks
    target = tmp_path / "r.csv"
    target.write_text("old\n")
    t = np.linspace(0.0, 1.0, 101)
    with pytest.raises(KeyboardInterrupt):
        Result(t=t, y=np.column_stack([t, t]), state_names=["x", "x_dot"], outputs={}, n_coordinates=1).save(target)
    assert [p.name for p in tmp_path.iterdir()] == ["r.csv"] and target.read_text() == "old\n"
    fresh = tmp_path / "new.csv"
    with pytest.raises(KeyboardInterrupt):
        Result(t=t, y=np.column_stack([t, t]), state_names=["x", "x_dot"], outputs={}, n_coordinates=1).save(fresh)
    assert [p.name for p in tmp_path.iterdir()] == ["r.csv"]


def test_csv_columns_of_different_lengths_are_refused(tmp_path):
    from lagcodegen.errors import LagcodegenError
    from lagcodegen.result import write_csv
    with pytest.raises(LagcodegenError, match="differ in length"):
        write_csv(tmp_path / "r.csv", {"t": np.zeros(3), "x": np.zeros(2)})
    with pytest.raises(LagcodegenError, match="one value per row"):
        write_csv(tmp_path / "r.csv", {"t": np.zeros((3, 2))})
    assert not list(tmp_path.iterdir())
