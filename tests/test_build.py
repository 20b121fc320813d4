"""The cffi build: content-hash cache, atomic publication, concurrent builds, compiler errors."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen import CompileError, Scene, derive, generate_c, systems

ROOT = Path(__file__).resolve().parents[1]


def is_runtime(entry) -> bool:
    """The cache entry of the model-independent runtime (built once into whichever cache is first)."""
    return entry.is_dir() and any(f.name.startswith("_lcg_runtime_") for f in entry.iterdir())


def test_second_build_is_a_cache_hit(tmp_path, monkeypatch):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    code = generate_c(Scene(derive(systems.pendulum()), prefix="cachehit"))
    first = lcg.build_code(code)
    second = lcg.build_code(code)
    assert not first.cached and second.cached
    assert first.path == second.path
    entries = [p for p in tmp_path.iterdir() if not is_runtime(p)]
    assert len(entries) == 1 and not entries[0].name.startswith(".build")  # no temp folder left
    assert entries[0] == first.path.parent


def test_model_library_joins_each_table_with_its_functions(tmp_path, monkeypatch):
    """Small model libraries compile the table in the translation unit of the functions it points
    to, at MODEL_CFLAGS (the runtime at DEFAULT_CFLAGS); the library's functions are the model's."""
    from lagcodegen.build import MODEL_CFLAGS, DEFAULT_CFLAGS
    assert MODEL_CFLAGS != DEFAULT_CFLAGS and "-O1" in MODEL_CFLAGS and "-DLCG_COLD_JACOBIAN" in MODEL_CFLAGS
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    built = lcg.build_code(generate_c(Scene(derive(systems.pendulum()), prefix="unitpend")))
    folder = built.path.parent
    assert (folder / "unitpend_unit.c").read_text() == '#include "unitpend.c"\n#include "unitpend_table.c"\n'
    sim = lcg.compile_model(systems.pendulum(), prefix="unitpend")
    ydot = sim.rhs(0.0, [0.5, 0.0])
    assert ydot[1] == pytest.approx(-9.81 * np.sin(0.5))  # l = 1: theta'' = -g sin(theta)


def test_changed_source_changes_the_key(tmp_path, monkeypatch):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    eom = derive(systems.pendulum())
    a = lcg.build_code(generate_c(Scene(eom, prefix="keyed")))
    b = lcg.build_code(generate_c(Scene(eom, prefix="keyed", outputs=["energy"])))
    assert a.path != b.path


def test_compiler_failure_raises_with_compiler_output(tmp_path, monkeypatch):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    code = generate_c(Scene(derive(systems.pendulum()), prefix="broken"))
    code.files[code.source_name] += "\nthis is not C;\n"
    with pytest.raises(CompileError) as info:
        lcg.build_code(code)
    assert "error" in info.value.output and "broken.c" in info.value.output
    assert "compiler output" in str(info.value)
    assert not [p for p in tmp_path.iterdir() if not p.name.startswith(".")]  # nothing published
    assert not list(tmp_path.glob(".build-*"))  # and no temp folder left behind


def test_missing_compiler_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    code = generate_c(Scene(derive(systems.pendulum()), prefix="nocc"))
    with pytest.raises(CompileError, match="no-such-cc"):
        lcg.build_code(code, cc="no-such-cc")


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
    published = [p for p in tmp_path.iterdir() if not p.name.startswith(".") and not is_runtime(p)]
    code_entries = [p for p in published if (p / "code.pickle").is_file()]  # the pipeline cache's
    assert len(code_entries) == 1 and len(published) == 2  # one generated code, one library
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


# ---------------------------------------------------------------------- the cache is executed code
# A cached module runs in the process that loads it: only the user's own, intact entries are
# opened. "Another process" is simulated by forgetting the module this one has loaded (a real
# later run has nothing loaded); planted files replace the module by a new inode, so that the
# copy this test process has mapped is never truncated under it.

import errno  # noqa: E402
import hashlib  # noqa: E402
import importlib  # noqa: E402
import stat  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

from lagcodegen import LagcodegenError, ModelError  # noqa: E402

build_module = importlib.import_module("lagcodegen.build")
cache_module = importlib.import_module("lagcodegen.cache")

OTHER_UID = 54321


def fresh_build(prefix, **options):
    """A small native=False build (fast) of a pendulum under ``prefix``."""
    return lcg.build_code(generate_c(Scene(derive(systems.pendulum()), prefix=prefix, jacobian=False)),
                     native=False, **options)


def forget(built):
    """As if in a new process: the module is not loaded yet."""
    sys.modules.pop(built.module.__name__, None)


def replace_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + ".new")
    tmp.write_bytes(data)
    os.chmod(tmp, 0o755)
    os.replace(tmp, path)


def entry_of(built) -> Path:
    return built.path.parent


def test_published_entry_records_the_module_digest(tmp_path, monkeypatch):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    built = fresh_build("digested")
    recorded = (entry_of(built) / build_module.DIGEST_NAME).read_text().split()[0]
    assert recorded == hashlib.sha256(built.path.read_bytes()).hexdigest()
    for p in [entry_of(built), *entry_of(built).iterdir()]:
        st = os.lstat(p)
        assert st.st_uid == os.geteuid() and not st.st_mode & 0o022, p


def test_cache_root_is_created_private_under_umask_000(tmp_path, monkeypatch):
    root = tmp_path / "a" / "b" / "cache"
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(root))
    old = os.umask(0)
    try:
        assert build_module.cache_dir() == root
    finally:
        os.umask(old)
    assert stat.S_IMODE(root.stat().st_mode) == 0o700
    for parent in (root.parent, root.parent.parent):
        assert not parent.stat().st_mode & 0o022


@pytest.mark.parametrize("hostile", ["foreign", "group-writable", "world-writable"])
def test_untrusted_cache_root_is_not_used(tmp_path, monkeypatch, hostile):
    root = tmp_path / "shared"
    root.mkdir(mode=0o700)
    if hostile == "foreign":
        os.chown(root, OTHER_UID, OTHER_UID)
    else:
        os.chmod(root, 0o770 if hostile == "group-writable" else 0o707)
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(root))
    with pytest.warns(build_module.CacheWarning, match=f"{root}.*not used") as rec:
        built = fresh_build(f"untrusted_root_{hostile.replace('-', '_')}")
    assert len(rec) == 1 and "\n" not in str(rec[0].message)
    assert root not in built.path.parents and built.path.is_file()
    assert not list(root.iterdir())  # nothing written into the untrusted folder


@pytest.mark.parametrize("hostile", ["foreign-owner", "world-writable-module", "group-writable-folder",
                                     "symlinked-folder"])
def test_untrusted_cache_entry_is_not_loaded(tmp_path, monkeypatch, hostile):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    first = fresh_build(f"planted_{hostile.replace('-', '_')}")
    entry = entry_of(first)
    if hostile == "foreign-owner":
        for p in [entry, *entry.iterdir()]:
            os.chown(p, OTHER_UID, OTHER_UID)
    elif hostile == "world-writable-module":
        os.chmod(first.path, 0o757)
    elif hostile == "symlinked-folder":  # the entry points somewhere else
        elsewhere = tmp_path.parent / f"{tmp_path.name}-elsewhere"
        entry.rename(elsewhere)
        entry.symlink_to(elsewhere)
    else:
        os.chmod(entry, 0o770)
    forget(first)
    with pytest.warns(build_module.CacheWarning, match="not used") as rec:
        second = fresh_build(f"planted_{hostile.replace('-', '_')}")
    assert len(rec) == 1 and "\n" not in str(rec[0].message)
    assert not second.cached and hasattr(second.module.lib, f"planted_{hostile.replace('-', '_')}_rhs")
    if hostile == "foreign-owner":  # left alone, and the model built where only we write
        assert entry.is_dir() and os.lstat(entry).st_uid == OTHER_UID
        assert tmp_path not in second.path.parents
    else:  # our own entry: replaced by a sound one
        assert second.path == first.path and not entry.is_symlink()
        assert not os.lstat(entry).st_mode & 0o022 and not os.lstat(second.path).st_mode & 0o022
        forget(second)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert fresh_build(f"planted_{hostile.replace('-', '_')}").cached


@pytest.mark.parametrize("damage", ["truncated", "flipped-byte", "digest-missing", "not-importable"])
def test_damaged_cache_entry_is_rebuilt_never_loaded(tmp_path, monkeypatch, damage):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    prefix = f"damaged_{damage.replace('-', '_')}"
    first = fresh_build(prefix)
    data = first.path.read_bytes()
    digest_file = entry_of(first) / build_module.DIGEST_NAME
    if damage == "truncated":  # dlopen of this used to end in SIGBUS
        replace_bytes(first.path, data[: len(data) // 3])
    elif damage == "flipped-byte":
        k = len(data) // 2
        replace_bytes(first.path, data[:k] + bytes([data[k] ^ 0xFF]) + data[k + 1:])
    elif damage == "digest-missing":
        digest_file.unlink()
    else:  # intact digest of a module that does not import
        junk = b"\x7fELF not really a shared object" * 10
        replace_bytes(first.path, junk)
        digest_file.write_text(hashlib.sha256(junk).hexdigest() + "\n")
    forget(first)
    opened = []
    monkeypatch.setattr(build_module, "import_module", lambda name, path, _real=build_module.import_module:
                        (opened.append(Path(path)), _real(name, path))[1])
    with pytest.warns(build_module.CacheWarning, match="not used.*rebuilding") as rec:
        second = fresh_build(prefix)
    assert len(rec) == 1 and "\n" not in str(rec[0].message)
    if damage != "not-importable":  # verified before dlopen: the damaged file is never opened
        assert first.path not in opened
    assert not second.cached and second.path == first.path
    assert hashlib.sha256(second.path.read_bytes()).hexdigest() == digest_file.read_text().split()[0]
    assert hasattr(second.module.lib, f"{prefix}_rhs")
    forget(second)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert fresh_build(prefix).cached  # repaired for good
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_module_that_does_not_import_is_never_published(tmp_path, monkeypatch):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    code = generate_c(Scene(derive(systems.pendulum()), prefix="unimportable", jacobian=False))
    code.files["unimportable_extra.c"] = ("extern double lcg_no_such_symbol(double);\n"
                                          "double unimportable_extra(double x) { return lcg_no_such_symbol(x); }\n")
    with pytest.raises(LagcodegenError, match="does not import.*lcg_no_such_symbol"):
        lcg.build_code(code, native=False)
    assert not list(tmp_path.iterdir())  # neither an entry nor a build folder


@pytest.mark.parametrize("name", ["math", "stdlib", "float", "Python"])
def test_model_named_like_a_system_header_builds_and_runs(tmp_path, monkeypatch, name):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    model = systems.pendulum()
    model.name = name
    cm = lcg.compile_model(model, outputs=["energy"])
    res = cm.simulate([0, 0.5], q0=[0.5])
    assert res.success and cm.code.prefix == name


def test_prefix_of_a_fixed_generated_file_is_refused():
    with pytest.raises(ModelError, match="'sundials_api' is reserved"):
        Scene(derive(systems.pendulum()), prefix="sundials_api")


def test_stale_build_folders_are_removed(tmp_path, monkeypatch):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))
    old = time.time() - build_module.STALE_BUILD_SECONDS - 60
    ancient = time.time() - build_module.ABANDONED_BUILD_SECONDS - 60
    dead = 4_000_000  # above any pid_max: no such process
    planted = {
        f".build-abc123-{dead}-x1": (old, None, False),          # killed build: removed
        f".build-abc123-{dead}-x2": (time.time(), None, True),   # may still be moving: kept
        f".build-abc123-{os.getpid()}-x3": (old, None, True),    # its process runs: kept
        ".build-abc123-legacy": (ancient, None, False),          # older than any compile: removed
        f".build-abc123-{dead}-x4": (ancient, OTHER_UID, True),  # another user's: not ours to judge
        ".stale-abc123-1-x5": (time.time(), None, False),        # set aside for removal
    }
    for name, (mtime, uid, _) in planted.items():
        (tmp_path / name).mkdir()
        (tmp_path / name / "half.c").write_text("int x;\n")
        if uid is not None:
            os.chown(tmp_path / name, uid, uid)
        os.utime(tmp_path / name, (mtime, mtime))
    fresh_build("after_a_kill")
    left = {p.name for p in tmp_path.iterdir() if p.name.startswith(".")}
    assert left == {name for name, (_, _, kept) in planted.items() if kept}


def test_unwritable_cache_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(tmp_path))

    def refuse(*args, **kwargs):
        raise PermissionError(errno.EROFS, "Read-only file system")
    monkeypatch.setattr(cache_module.tempfile, "mkdtemp", refuse)
    with pytest.raises(LagcodegenError, match=f"{tmp_path}: Read-only file system; set LAGCODEGEN_CACHE"):
        fresh_build("readonly")


def test_uncreatable_cache_is_a_clear_error(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("LAGCODEGEN_CACHE", str(blocker / "cache"))
    with pytest.raises(LagcodegenError, match=f"cannot create the build cache folder {blocker / 'cache'}.*"
                                              "LAGCODEGEN_CACHE"):
        fresh_build("uncreatable")
