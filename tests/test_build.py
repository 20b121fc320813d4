"""The cffi build: content-hash cache, atomic publication, concurrent builds, compiler errors."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import lagcodegen as lcg
from lagcodegen import CompileError, Scene, derive, generate_c, systems

ROOT = Path(__file__).resolve().parents[1]


def test_second_build_is_a_cache_hit(tmp_path, monkeypatch):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    code = generate_c(Scene(derive(systems.pendulum()), prefix="cachehit"))
    first = lcg.build(code)
    second = lcg.build(code)
    assert not first.cached and second.cached
    assert first.path == second.path
    entries = [p for p in tmp_path.iterdir()]
    assert len(entries) == 1 and not entries[0].name.startswith(".build")  # no temp folder left


def test_changed_source_changes_the_key(tmp_path, monkeypatch):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    eom = derive(systems.pendulum())
    a = lcg.build(generate_c(Scene(eom, prefix="keyed")))
    b = lcg.build(generate_c(Scene(eom, prefix="keyed", outputs=["energy"])))
    assert a.path != b.path


def test_compiler_failure_raises_with_compiler_output(tmp_path, monkeypatch):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    code = generate_c(Scene(derive(systems.pendulum()), prefix="broken"))
    code.files[code.source_name] += "\nthis is not C;\n"
    with pytest.raises(CompileError) as info:
        lcg.build(code)
    assert "error" in info.value.output and "broken.c" in info.value.output
    assert "compiler output" in str(info.value)
    assert not [p for p in tmp_path.iterdir() if not p.name.startswith(".")]  # nothing published
    assert not list(tmp_path.glob(".build-*"))  # and no temp folder left behind


def test_missing_compiler_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    code = generate_c(Scene(derive(systems.pendulum()), prefix="nocc"))
    with pytest.raises(CompileError, match="no-such-cc"):
        lcg.build(code, cc="no-such-cc")


def test_two_processes_building_the_same_model_both_succeed(tmp_path):
    script = textwrap.dedent("""
        import sys
        import lagcodegen as lcg
        cm = lcg.compile_model(lcg.systems.double_pendulum(), outputs=["energy"], prefix="race")
        res = cm.simulate([0, 1], q0=[0.5, 0.1])
        print("OK", cm.cached, res.y[-1, 0])
    """)
    env = dict(os.environ, LAGCODEGEN_CACHE=str(tmp_path), PYTHONPATH=str(ROOT))
    procs = [subprocess.Popen([sys.executable, "-c", script], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(3)]
    outs = [p.communicate(timeout=600) for p in procs]
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0, err
        assert out.startswith("OK")
    finals = {out.split()[-1] for out, _ in outs}
    assert len(finals) == 1  # same module, same numbers
    published = [p for p in tmp_path.iterdir() if not p.name.startswith(".")]
    assert len(published) == 1
    assert not list(tmp_path.glob(".build-*"))


def test_written_sources_appear_atomically(tmp_path):
    code = generate_c(Scene(derive(systems.pendulum())))
    paths = code.write(tmp_path / "gen")
    assert sorted(p.name for p in paths) == ["pendulum.c", "pendulum.h"]
    assert not [p for p in (tmp_path / "gen").iterdir() if p.name.startswith(".")]
    assert (tmp_path / "gen" / "pendulum.c").read_text() == code.files["pendulum.c"]


def test_regeneration_is_byte_identical():
    a = generate_c(Scene(derive(systems.double_pendulum()), outputs=["energy", "positions"]))
    b = generate_c(Scene(derive(systems.double_pendulum()), outputs=["energy", "positions"]))
    assert a.files == b.files
