"""Large program-form sources cut into groups of functions (lagcodegen.codegen.c SPLIT_MIN_CHARS,
GROUP_CHARS) and compiled as several objects at once (lagcodegen.build): strict C both as one
translation unit and as every split, the same values as the uncut source, small sources untouched."""

import importlib
import subprocess

import numpy as np
import pytest

import lagcodegen.codegen.c as cmod
from lagcodegen import Scene, build_code, derive, generate_c, systems

bmod = importlib.import_module("lagcodegen.build")

from helpers import STRICT_CFLAGS


@pytest.fixture()
def small_groups(monkeypatch):
    """Groups of a few pieces on a small model: every path of the split runs."""
    monkeypatch.setattr(cmod, "PROGRAM_MIN_OPS", 0)
    monkeypatch.setattr(cmod, "CHUNK_STATEMENTS", 5)
    monkeypatch.setattr(cmod, "SPLIT_MIN_CHARS", 2000)
    monkeypatch.setattr(cmod, "GROUP_CHARS", 1500)


def scene(n, form, prefix):
    eom = derive(systems.n_link_pendulum(n, name=prefix))
    return Scene(eom, jacobian=form != "none", jacobian_form=form if form != "none" else "expanded",
                 outputs=["energy"], prefix=prefix)


@pytest.mark.parametrize("form", ["none", "expanded", "tangent"])
def test_split_sources_compile_with_strict_warnings_whole_and_in_parts(tmp_path, cc, small_groups, form):
    code = generate_c(scene(6, form, f"sp_{form}"))
    groups = code.split[code.source_name]
    assert groups > 3
    code.write(tmp_path)
    runs = [[]] + [[f"-DLCG_PARTS={k}", f"-DLCG_PART={j}"] for k in (2, 3) for j in range(k)]
    for defines in runs:
        proc = subprocess.run([cc, *STRICT_CFLAGS, "-O2", "-fPIC", *defines, "-c", code.source_name, "-o", "m.o"],
                              cwd=tmp_path, capture_output=True, text=True)
        assert proc.returncode == 0, (defines, proc.stderr)
    for k in (2, 3):  # the objects of a split link into one library (each piece defined once)
        objs = []
        for j in range(k):
            objs.append(f"p{k}_{j}.o")
            subprocess.run([cc, *STRICT_CFLAGS, "-O2", "-fPIC", f"-DLCG_PARTS={k}", f"-DLCG_PART={j}", "-c",
                            code.source_name, "-o", objs[-1]], cwd=tmp_path, check=True)
        proc = subprocess.run([cc, "-shared", *objs, "-o", f"lib{k}.so", "-lm"], cwd=tmp_path, capture_output=True,
                              text=True)
        assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("form", ["none", "tangent"])
def test_split_build_gives_the_values_of_the_uncut_source(monkeypatch, small_groups, form):
    """build_code() compiles a split source as split_parts objects (forced to 2 here, whatever the
    cores): rhs and jac equal those of the same program printed without groups."""
    monkeypatch.setattr(bmod, "split_parts", lambda groups: min(groups, 2))
    split = build_code(generate_c(scene(6, form, f"sb_{form}")), native=False)
    assert split.code.split
    monkeypatch.setattr(cmod, "SPLIT_MIN_CHARS", 10 ** 12)
    whole = build_code(generate_c(scene(6, form, f"sw_{form}")), native=False)
    assert not whole.code.split and "LCG_PART" not in whole.code.files[whole.code.source_name]
    rng = np.random.default_rng(3)
    for _ in range(5):
        y = rng.uniform(-2.0, 2.0, whole.ny)
        np.testing.assert_array_equal(split.rhs(0.1, y), whole.rhs(0.1, y))
        if form != "none":
            np.testing.assert_array_equal(split.jac(0.1, y), whole.jac(0.1, y))


def test_only_large_sources_are_split():
    """Below SPLIT_MIN_CHARS of pieces the source is one translation unit, unchanged (static
    pieces, no LCG_PART); a 50-link chain's right-hand side (160 kB) is cut."""
    small = generate_c(scene(20, "none", "sp_small"))
    assert not small.split
    text = small.files[small.source_name]
    assert "LCG_PART" not in text and "static NOINLINE void values0(" in text
    large = generate_c(scene(50, "none", "sp_large"))
    groups = large.split[large.source_name]
    text = large.files[large.source_name]
    assert groups >= 2 and text.count("#if !defined(LCG_PART) ||") == groups + 2
    assert "PIECE NOINLINE void values0(" in text


def test_split_parts_policy(monkeypatch):
    """One object per core, at most one per group; one core or one group: the file as it is."""
    monkeypatch.setattr(bmod.os, "cpu_count", lambda: 2)
    assert [bmod.split_parts(g) for g in (1, 2, 8)] == [1, 2, 2]
    monkeypatch.setattr(bmod.os, "cpu_count", lambda: 1)
    assert bmod.split_parts(8) == 1
    monkeypatch.setattr(bmod.os, "cpu_count", lambda: None)
    assert bmod.split_parts(8) == 1
