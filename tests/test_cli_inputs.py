"""Input tables on the command line: `lagcodegen simulate ... --input NAME=FILE[:KIND]` and
`lagcodegen sweep ... --input ...` (the same table for every member) against the analytic step
response of a damped oscillator; bad files and names are usage errors naming the input."""

import numpy as np

from lagcodegen.cli import main

FORCED = """
[model]
name = "forced_cli"
coordinates = ["x"]

[parameters]
m = 1.0
k = 4.0
c = 0.4

[inputs]
F = 0.0

[[particles]]
name = "mass"
mass = "m"
position = ["x", 0]

[energy]
potential = "k*x**2/2"
dissipation = "c*x_dot**2/2"

[[generalized_forces]]
coordinate = "x"
expr = "F"

[simulation]
t_end = 10.0
n_out = 101
rtol = 1e-10
atol = 1e-12
initial = { x = 0.0 }
"""


def step_response(t, k, t_step=1.3, F0=2.0, m=1.0, c=0.4):
    w0, zeta = np.sqrt(k / m), c / (2 * np.sqrt(k * m))
    wd = w0 * np.sqrt(1 - zeta ** 2)
    s = np.clip(t - t_step, 0.0, None)
    x = F0 / k * (1 - np.exp(-zeta * w0 * s) * (np.cos(wd * s) + zeta / np.sqrt(1 - zeta ** 2) * np.sin(wd * s)))
    return np.where(t >= t_step, x, 0.0)


def test_simulate_and_sweep_take_input_tables(tmp_path, capsys):
    model = tmp_path / "forced.toml"
    model.write_text(FORCED)
    (tmp_path / "step.txt").write_text("0 0\n1.3 2\n")
    out = tmp_path / "r.csv"
    assert main(["simulate", str(model), "-o", str(out), "--input", f"F={tmp_path / 'step.txt'}:zoh", "-q"]) == 0
    res = np.genfromtxt(out, delimiter=",", names=True)
    assert np.max(np.abs(res["x"] - step_response(res["t"], 4.0))) < 1e-8
    table = tmp_path / "s.csv"
    assert main(["sweep", str(model), "-o", str(table), "--grid", "k=2:6:3", "--input",
                 f"F={tmp_path / 'step.txt'}:zoh", "-q"]) == 0
    rows = np.genfromtxt(table, delimiter=",", names=True)
    assert np.allclose(rows["final_x"], step_response(10.0, rows["k"]), rtol=0, atol=1e-8)
    # a linear table (the default kind) ramps the force: a different answer
    assert main(["simulate", str(model), "-o", str(out), "--input", f"F={tmp_path / 'step.txt'}", "-q"]) == 0
    ramp = np.genfromtxt(out, delimiter=",", names=True)
    assert np.max(np.abs(ramp["x"] - res["x"])) > 1e-2
    capsys.readouterr()
    assert main(["simulate", str(model), "-o", str(out), "--input", f"F={tmp_path / 'none.txt'}", "-q"]) == 2
    assert "--input F: cannot read" in capsys.readouterr().err
    (tmp_path / "bad.txt").write_text("0 0\n2 1\n1 3\n")
    assert main(["simulate", str(model), "-o", str(out), "--input", f"F={tmp_path / 'bad.txt'}", "-q"]) == 2
    assert "--input F: times must increase strictly" in capsys.readouterr().err
    assert main(["simulate", str(model), "-o", str(out), "--input", "F", "-q"]) == 2


def test_input_tables_that_are_not_regular_files_or_too_large_are_refused(tmp_path, capsys, monkeypatch):
    """--input reads a regular file of at most INPUT_TABLE_MAX_BYTES (64 MiB): a FIFO (or a device
    such as /dev/zero, read without end into a bare MemoryError) is refused without waiting for a
    writer, a folder too, and a larger file before it is read; each a usage error (exit 2) naming
    the input, the file and, for the size, the limit."""
    import os
    import threading
    import time

    from lagcodegen.cli import common
    model = tmp_path / "forced.toml"
    model.write_text(FORCED)
    out = tmp_path / "r.csv"
    fifo = tmp_path / "table.fifo"
    os.mkfifo(fifo)

    def writer():  # a table for whoever opens the FIFO for reading (within 5 s): never the new code's open
        end = time.monotonic() + 5
        while time.monotonic() < end:
            try:
                fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
            except OSError:
                time.sleep(0.01)
                continue
            try:
                os.write(fd, b"0 0\n1.3 2\n")
            except OSError:
                pass
            os.close(fd)
            return
    thread = threading.Thread(target=writer, daemon=True)
    thread.start()
    capsys.readouterr()
    assert main(["simulate", str(model), "-o", str(out), "--input", f"F={fifo}", "-q"]) == 2
    assert f"--input F: '{fifo}' is a FIFO, not a regular file" in capsys.readouterr().err
    assert main(["simulate", str(model), "-o", str(out), "--input", f"F={tmp_path}", "-q"]) == 2
    assert "--input F:" in capsys.readouterr().err and not out.exists()
    thread.join()

    assert common.INPUT_TABLE_MAX_BYTES == 64 * 2**20
    table = tmp_path / "step.txt"
    table.write_text("0 0\n" + "".join(f"{1 + k * 1e-3:.6f} 2\n" for k in range(20)))
    monkeypatch.setattr(common, "INPUT_TABLE_MAX_BYTES", 100)
    assert main(["simulate", str(model), "-o", str(out), "--input", f"F={table}", "-q"]) == 2
    err = capsys.readouterr().err
    assert f"--input F: '{table}' is larger than the input table limit of 100 bytes" in err and "Traceback" not in err
    monkeypatch.setattr(common, "INPUT_TABLE_MAX_BYTES", 10_000)
    assert main(["simulate", str(model), "-o", str(out), "--input", f"F={table}:zoh", "-q"]) == 0
