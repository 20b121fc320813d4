"""`lagcodegen generate` as a build step, at the command line: Python models (FILE.py:FUNCTION),
the manifest (answers without deriving), --list-outputs, --depfile, --stamp, --cmake-dir."""

import json
import os
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from lagcodegen.cli import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"

MODELS = '''
import lagcodegen as lcg
from mymodels_parts import LENGTH


def double_pendulum():
    return lcg.systems.double_pendulum()


def pendulum():
    return lcg.systems.pendulum()


def broken():
    raise RuntimeError("boom")


def not_a_model():
    return LENGTH
'''


@pytest.fixture
def run(capsys):
    """lagcodegen's command line, in this process (the command itself: test_cmake_dir_command)."""
    def call(*args):
        capsys.readouterr()
        try:
            code = main([str(a) for a in args])
        except SystemExit as exc:
            code = exc.code
        out, err = capsys.readouterr()
        return SimpleNamespace(returncode=code, stdout=out, stderr=err)
    return call


def test_python_model_manifest_depfile_stamp(tmp_path, run):
    (tmp_path / "mymodels.py").write_text(MODELS)
    (tmp_path / "mymodels_parts.py").write_text("LENGTH = 1.0\n")
    out, dep, stamp = tmp_path / "gen", tmp_path / "dp.d", tmp_path / "dp.stamp"
    spec = f"{tmp_path / 'mymodels.py'}:double_pendulum"
    # --list-outputs: the names, nothing written
    listed = run("generate", spec, "-o", out, "--list-outputs", "-q")
    assert listed.returncode == 0, listed.stderr
    names = ["double_pendulum.c", "double_pendulum.h", "double_pendulum.lagcodegen.json"]
    assert listed.stdout.splitlines() == [str(out / n) for n in names] and not out.exists()

    proc = run("generate", spec, "-o", out, "--depfile", dep, "--stamp", stamp)
    assert proc.returncode == 0, proc.stderr
    assert "executed" in proc.stderr and "derived" in proc.stderr
    assert sorted(p.name for p in out.iterdir()) == names
    assert stamp.read_text().splitlines() == listed.stdout.splitlines()
    depfile = dep.read_text()
    assert depfile.startswith(f"{stamp}: \\\n")
    for needed in ("mymodels.py", "mymodels_parts.py", "lagcodegen/cli/__init__.py", "model.c.j2", "lagcodegenConfig.cmake"):
        assert needed in depfile, needed
    manifest = json.loads((out / "double_pendulum.lagcodegen.json").read_text())
    assert set(manifest["inputs"]["files"]) == {"mymodels.py", "mymodels_parts.py"}
    assert manifest["inputs"]["model"] == "mymodels.py:double_pendulum"
    assert {"lagcodegen", "sympy", "symengine", "sources"} <= set(manifest["generator"])
    assert set(manifest["files"]) == {"double_pendulum.c", "double_pendulum.h"}

    # same inputs: generate, --check and --list-outputs answer from the manifest (no derivation);
    # generate still touches the stamp and writes nothing
    mtimes = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    stamped = stamp.stat().st_mtime_ns
    time.sleep(0.02)
    again = run("generate", spec, "-o", out, "--depfile", dep, "--stamp", stamp)
    assert again.returncode == 0 and "derived" not in again.stderr and "manifest" in again.stderr
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == mtimes
    assert stamp.stat().st_mtime_ns > stamped
    check = run("generate", spec, "-o", out, "--check")
    assert check.returncode == 0 and "derived" not in check.stderr, check.stderr
    assert run("generate", spec, "-o", out, "--list-outputs", "-q").stdout == listed.stdout

    # a file edited by hand: --check says which, still without deriving
    header = out / "double_pendulum.h"
    header.write_text(header.read_text() + "/* edited */\n")
    check = run("generate", spec, "-o", out, "--check")
    assert check.returncode == 5 and "double_pendulum.h" in check.stderr and "derived" not in check.stderr
    assert run("generate", spec, "-o", out, "-q").returncode == 0
    # a module the model file imports changed: an input changed, the manifest is stale
    (tmp_path / "mymodels_parts.py").write_text("LENGTH = 2.0\n")
    check = run("generate", spec, "-o", out, "--check")
    assert check.returncode == 5 and "double_pendulum.lagcodegen.json" in check.stderr
    # other options: the manifest does not match, the code differs
    check = run("generate", spec, "-o", out, "--check", "--no-jacobian")
    assert check.returncode == 5 and "double_pendulum.c" in check.stderr


def test_python_model_errors_are_input_errors(tmp_path, run):
    (tmp_path / "mymodels.py").write_text(MODELS)
    (tmp_path / "mymodels_parts.py").write_text("LENGTH = 1.0\n")
    models = tmp_path / "mymodels.py"
    for spec, message in [(f"{models}:broken", "RuntimeError: boom"), (f"{models}:missing", "no function 'missing'"),
                          (f"{models}:not_a_model", "returned float"), (str(models), "name the function"),
                          (f"{tmp_path / 'none.py'}:f", "no such Python model file")]:
        proc = run("generate", spec, "-o", tmp_path / "out", "-q")
        assert proc.returncode == 1 and message in proc.stderr, (spec, proc.stderr)
    # simulate and info take Python models too
    info = run("info", f"{models}:pendulum")
    assert info.returncode == 0 and "model pendulum: 1 coordinates" in info.stdout
    # bad command line
    assert run("generate", EXAMPLES / "pendulum.toml", "-o", tmp_path / "o", "--check", "--list-outputs") \
        .returncode == 2


def test_cmake_dir_command():
    proc = subprocess.run([sys.executable, "-m", "lagcodegen", "--cmake-dir"], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0
    folder = Path(proc.stdout.strip())
    assert (folder / "lagcodegenConfig.cmake").is_file() and (folder / "lagcodegenConfigVersion.cmake").is_file()


def test_toml_depfile_relative_paths(tmp_path, run, monkeypatch):
    # a relative stamp path stays relative in the depfile (Ninja compares it with its own path)
    monkeypatch.chdir(tmp_path)
    proc = run("generate", EXAMPLES / "pendulum.toml", "-o", "gen", "--stamp", "p.stamp", "--depfile", "p.d", "-q")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "p.d").read_text().startswith("p.stamp: \\\n")
    assert str(EXAMPLES / "pendulum.toml") in (tmp_path / "p.d").read_text()
    assert (tmp_path / "p.stamp").read_text().splitlines() == [
        os.path.join("gen", n) for n in ("pendulum.c", "pendulum.h", "pendulum.lagcodegen.json")]


def _tampered(out: Path, name: str, entry: str) -> None:
    """Add ``entry`` to the manifest's list of files, as a hostile repository could ship it."""
    path = out / f"{name}.lagcodegen.json"
    record = json.loads(path.read_text())
    record["files"][entry] = "0" * 64
    path.write_text(json.dumps(record))


@pytest.mark.parametrize("entry", ["../../outside.txt", "/etc/hostname", "sub/../../outside.txt",
                                   "pend.c;/tmp/victim", "a\\..\\b", "C:/x.c", "./pendulum.c", "x\ny"])
def test_tampered_manifest_names_are_refused(tmp_path, run, entry):
    """A manifest listing a name outside its folder is refused by generate, --check and
    --list-outputs alike, naming the manifest and the entry; nothing outside is listed or read."""
    model, out = EXAMPLES / "pendulum.toml", tmp_path / "gen"
    assert run("generate", model, "-o", out, "-q").returncode == 0
    _tampered(out, "pendulum", entry)
    for extra in ([], ["--check"], ["--list-outputs"]):
        proc = run("generate", model, "-o", out, "-q", *extra)
        assert proc.returncode == 1, (extra, proc.stdout, proc.stderr)
        assert "pendulum.lagcodegen.json" in proc.stderr and "delete it" in proc.stderr
        assert proc.stdout == "" and "Traceback" not in proc.stderr


def test_manifest_entries_that_are_not_regular_files(tmp_path, run):
    """A FIFO in place of a generated file is never opened (--check would block forever): the
    manifest is refused; a folder symlinked outside is refused too, and a symlinked file that
    is not listed by a tampered manifest is out of date and replaced, not followed."""
    model, out = EXAMPLES / "pendulum.toml", tmp_path / "gen"
    assert run("generate", model, "-o", out, "-q").returncode == 0
    (out / "pendulum.c").unlink()
    os.mkfifo(out / "pendulum.c")
    for extra in ([], ["--check"], ["--list-outputs"]):
        proc = run("generate", model, "-o", out, "-q", *extra)
        assert proc.returncode == 1 and "not a regular file" in proc.stderr, (extra, proc.stderr)
    (out / "pendulum.c").unlink()
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "x.c").write_text("precious\n")
    os.symlink(outside, out / "sub")
    _tampered(out, "pendulum", "sub/x.c")
    proc = run("generate", model, "-o", out, "-q", "--list-outputs")
    assert proc.returncode == 1 and "sub/x.c" in proc.stderr and proc.stdout == ""
    (out / "sub").unlink()
    # a regular manifest, the generated source replaced by a link to a file outside
    (out / "pendulum.lagcodegen.json").unlink()
    assert run("generate", model, "-o", out, "-q").returncode == 0
    (out / "pendulum.h").unlink()
    os.symlink(outside / "x.c", out / "pendulum.h")
    proc = run("generate", model, "-o", out, "-q")
    assert proc.returncode == 1 and "pendulum.h" in proc.stderr
    assert (outside / "x.c").read_text() == "precious\n"


EVENTS_MODEL = """
[model]
name = "evpend"
coordinates = ["theta"]
[parameters]
g = 9.81
l = 1.0
m = 1.0
[[particles]]
name = "bob"
mass = "m"
position = ["l*sin(theta)", "-l*cos(theta)"]
[gravity]
g = "g"
[[events]]
name = "cross"
expr = "theta - 0.25"
direction = 0
terminal = false
[[events]]
name = "fast"
expr = "theta_dot*theta_dot - g"
direction = 1
terminal = true
[simulation]
runtime_parameters = ["g"]
t_end = 3.0
initial = { theta = 1.0 }
"""


def test_generate_writes_the_event_functions_of_a_model_file(tmp_path, run, cc):
    """`generate` of a model file with [[events]] writes <prefix>_events.c beside the model's code
    (listed, in the manifest): it compiles strictly, and its gout are the events' expressions; in
    Fortran the events are said to be printed in C only."""
    import ctypes
    from helpers import STRICT_CFLAGS
    model = tmp_path / "evpend.toml"
    model.write_text(EVENTS_MODEL)
    out = tmp_path / "gen"
    listed = run("generate", model, "-o", out, "--list-outputs", "-q")
    assert str(out / "evpend_events.c") in listed.stdout.splitlines()
    assert run("generate", model, "-o", out, "-q").returncode == 0
    manifest = json.loads((out / "evpend.lagcodegen.json").read_text())
    assert "evpend_events.c" in manifest["files"]
    lib = tmp_path / "libev.so"
    proc = subprocess.run([cc, *STRICT_CFLAGS, "-shared", "-fPIC", str(out / "evpend_events.c"), "-o", str(lib),
                           "-lm"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    fn = ctypes.CDLL(str(lib)).evpend_events
    fn.restype = ctypes.c_int
    y, p, g = (ctypes.c_double * 2)(0.7, -3.5), (ctypes.c_double * 1)(9.0), (ctypes.c_double * 2)()
    assert fn(ctypes.c_double(0.0), y, p, g) == 0
    assert list(g) == [0.7 - 0.25, 3.5 * 3.5 - 9.0]
    fortran = run("generate", model, "-o", tmp_path / "genf", "--lang", "fortran")
    assert fortran.returncode == 0 and "printed in C only" in fortran.stderr
    assert not (tmp_path / "genf" / "evpend_events.c").exists()
