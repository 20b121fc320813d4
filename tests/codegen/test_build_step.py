"""lagcodegen inside other projects' builds, with the real tools: a CMake project using
find_package(lagcodegen) + lagcodegen_generate (C, C++ and Fortran programs) with Ninja and with
Makefiles, regenerating when and only when it should; bundles under FetchContent, installed and
found by find_package and pkg-config; the Makefile's install with DESTDIR; the README's Meson
and Make snippets."""

import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen import Scene, generate_c
from lagcodegen.modelfile import load_model

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
BIN = str(Path(sys.executable).parent)
ENV = {**os.environ, "PATH": BIN + os.pathsep + os.environ.get("PATH", "")}
STEPS, T_END, THETA0, G, L = 1000, 1.0, 1.0, 9.81, 0.8

# Fixed-step RK4 of the generated pendulum (run-time parameter g, l folded to 0.8) from theta = 1.
RK4 = r"""
#include <stdio.h>
#include "pend.h"
static void step(double t, double *y, double h, const double *p) {
    double k[4][PEND_NY], tmp[PEND_NY];
    int s, i;
    for (s = 0; s < 4; s++) {
        double c = s == 0 ? 0.0 : (s == 3 ? 1.0 : 0.5);
        for (i = 0; i < PEND_NY; i++) tmp[i] = y[i] + (s ? c * h * k[s - 1][i] : 0.0);
        pend_rhs(t + c * h, tmp, p, k[s]);
    }
    for (i = 0; i < PEND_NY; i++) y[i] += h / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
}
int main(void) {
    double y[PEND_NY] = {%(theta0)r, 0.0}, p[PEND_NP] = {%(g)r};
    int n;
    for (n = 0; n < %(steps)d; n++) step(n * (%(t_end)r / %(steps)d), y, %(t_end)r / %(steps)d, p);
    printf("%%.17g %%.17g\n", y[0], y[1]);
    return 0;
}
""" % dict(theta0=THETA0, g=G, steps=STEPS, t_end=T_END)

FORTRAN = """program mainf
  use iso_c_binding
  use pendf_mod
  implicit none
  real(c_double) :: y(2), p(1), ydot(2)
  integer(c_int) :: rc
  y = [1.0d0, 0.0d0]
  rc = pendf_rhs(0.0d0, y, p, ydot)
  print '(i0, 2es25.16)', rc, ydot
end program mainf
"""

CONSUMER = """cmake_minimum_required(VERSION 3.20)
project(consumer LANGUAGES C CXX Fortran)
find_package(lagcodegen 0.1 CONFIG REQUIRED)
lagcodegen_generate(TARGET pend MODEL pendulum.toml PREFIX pend OUTPUTS energy RUNTIME_PARAMETERS g SET l=0.8)
lagcodegen_generate(TARGET pendf MODEL pendulum.toml PREFIX pendf LANG Fortran RUNTIME_PARAMETERS)
add_executable(main main.c)
target_link_libraries(main PRIVATE pend)
add_executable(main_cpp main.cpp)
target_link_libraries(main_cpp PRIVATE pend)
add_executable(mainf mainf.f90)
target_link_libraries(mainf PRIVATE pendf)
"""


def run(cmd, cwd, check=True, env=ENV):
    proc = subprocess.run([str(c) for c in cmd], cwd=cwd, capture_output=True, text=True, env=env, timeout=300)
    if check:
        assert proc.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{proc.stdout}\n{proc.stderr}"
    return proc


OWN = (str(Path(lcg.__file__).parent), str(ROOT / "templates"))


def nothing_to_do(build, cwd) -> bool:
    """`ninja -n` has nothing to do. lagcodegen's own files are inputs of every generation: in a
    source tree edited meanwhile (not in an installed wheel) a build first catches up with them."""
    for _ in range(3):
        proc = run(["ninja", "-C", build, "-n", "-d", "explain"], cwd)
        if "no work to do" in proc.stdout:
            return True
        if not any(f"input {own}" in proc.stderr for own in OWN):
            print(proc.stderr)
            return False
        run(["ninja", "-C", build], cwd)
    return False


def own_files_newer_than(path: Path) -> bool:
    from lagcodegen.buildstep import own_files
    return any(f.stat().st_mtime_ns > path.stat().st_mtime_ns for f in own_files())


def numbers(text):
    return np.array([float(v) for v in text.split()])


def cmake_dir():
    return run([Path(BIN) / "lagcodegen", "--cmake-dir"], ROOT).stdout.strip()


@pytest.fixture(scope="module")
def reference():
    """lagcodegen's own CVODE solution of the same scene, to 1e-12."""
    mf = load_model(EXAMPLES / "pendulum.toml")
    scene = Scene(mf.derive(), outputs=["energy"], runtime_parameters=["g"], values={"l": L}, prefix="pend")
    res = lcg.build_code(generate_c(scene)).simulate([0.0, T_END], q0=[THETA0], params={"g": G}, rtol=1e-12,
                                                 atol=1e-12)
    return res.y[-1]


def consumer_project(path: Path) -> Path:
    path.mkdir()
    shutil.copy(EXAMPLES / "pendulum.toml", path / "pendulum.toml")
    (path / "main.c").write_text(RK4)
    (path / "main.cpp").write_text(RK4.replace("<stdio.h>", "<cstdio>"))
    (path / "mainf.f90").write_text(FORTRAN)
    (path / "CMakeLists.txt").write_text(CONSUMER)
    return path


def test_cmake_ninja_consumer(tmp_path, tools, reference):
    src = consumer_project(tmp_path / "src")
    build = tmp_path / "build"
    run(["cmake", "-S", src, "-B", build, "-G", "Ninja", f"-Dlagcodegen_DIR={cmake_dir()}"], tmp_path)
    first = run(["ninja", "-C", build], tmp_path).stdout
    assert "lagcodegen: generating pend " in first and "lagcodegen: generating pendf " in first
    for program in ("main", "main_cpp"):  # C and C++ against the generated library match simulate()
        y = numbers(run([build / program], tmp_path).stdout)
        assert np.allclose(y, reference, rtol=0, atol=1e-9), (program, y, reference)
    fortran = numbers(run([build / "mainf"], tmp_path).stdout)  # all folded: l = 1, g = 9.81
    assert fortran[0] == 0 and fortran[2] == pytest.approx(-9.81 * np.sin(1.0), rel=1e-14)
    generated = build / "lagcodegen" / "pend"
    assert sorted(p.name for p in generated.iterdir()) == ["pend.c", "pend.h", "pend.lagcodegen.json"]

    # nothing changed: nothing to do
    assert nothing_to_do(build, tmp_path)
    # the model touched, same content: lagcodegen runs again (from its manifest), nothing recompiles
    mtime = (generated / "pend.c").stat().st_mtime_ns
    time.sleep(0.02)
    os.utime(src / "pendulum.toml")
    again = run(["ninja", "-C", build, "-d", "explain"], tmp_path)
    assert "lagcodegen: generating pend " in again.stdout
    assert "Building C object" not in again.stdout and "Linking" not in again.stdout
    assert (generated / "pend.c").stat().st_mtime_ns == mtime
    assert nothing_to_do(build, tmp_path)
    # the model changed: the folded-parameter library recompiles, the other one does not change
    text = (src / "pendulum.toml").read_text()
    (src / "pendulum.toml").write_text(text.replace("l = 1.0", "l = 2.0"))
    changed = run(["ninja", "-C", build], tmp_path).stdout
    assert "pendf.f90" in changed and "pend.c.o" not in changed
    assert numbers(run([build / "mainf"], tmp_path).stdout)[2] == pytest.approx(-9.81 / 2 * np.sin(1.0), rel=1e-14)
    assert nothing_to_do(build, tmp_path)
    # an option changed (SET): reconfigure, regenerate, rebuild, other numbers
    (src / "CMakeLists.txt").write_text(CONSUMER.replace("SET l=0.8", "SET l=0.5"))
    rebuilt = run(["ninja", "-C", build], tmp_path).stdout
    assert "lagcodegen: generating pend " in rebuilt and "pend.c.o" in rebuilt
    assert not np.allclose(numbers(run([build / "main"], tmp_path).stdout), reference, atol=1e-3)
    assert nothing_to_do(build, tmp_path)


def test_cmake_makefiles_consumer_with_python_model(tmp_path, tools, reference):
    src = tmp_path / "src"
    src.mkdir()
    (src / "models.py").write_text("from lagcodegen.modelfile import load_model\n\n\ndef pendulum():\n"
                                   f"    return load_model({str(EXAMPLES / 'pendulum.toml')!r}).model\n")
    (src / "main.c").write_text(RK4)
    (src / "CMakeLists.txt").write_text(
        "cmake_minimum_required(VERSION 3.20)\nproject(consumer LANGUAGES C)\n"
        "find_package(lagcodegen CONFIG REQUIRED)\n"
        "lagcodegen_generate(TARGET pend MODEL models.py:pendulum PREFIX pend OUTPUTS energy RUNTIME_PARAMETERS g "
        "SET l=0.8 LIBRARY SHARED)\n"
        "add_executable(main main.c)\ntarget_link_libraries(main PRIVATE pend)\n")
    build = tmp_path / "build"
    # found as scikit-build-core's cmake.root entry point finds it: lagcodegen_ROOT = the package folder
    run(["cmake", "-S", src, "-B", build, "-G", "Unix Makefiles", f"-Dlagcodegen_ROOT={Path(lcg.__file__).parent}"],
        tmp_path)
    out = run(["make", "-C", build], tmp_path).stdout
    assert "lagcodegen: generating pend" in out and (build / "libpend.so").exists()
    assert np.allclose(numbers(run([build / "main"], tmp_path).stdout), reference, rtol=0, atol=1e-9)
    stamp = build / "CMakeFiles" / "lagcodegen" / "pend.stamp"
    before = stamp.stat().st_mtime_ns
    out = run(["make", "-C", build], tmp_path).stdout  # a second build does no work
    if not own_files_newer_than(stamp):  # (unless lagcodegen's source tree was edited meanwhile)
        assert "generating" not in out and "Building" not in out and "Linking" not in out
        assert stamp.stat().st_mtime_ns == before
    before = stamp.stat().st_mtime_ns
    time.sleep(0.02)
    os.utime(src / "models.py")  # the Python model file is an input (its depfile entry)
    out = run(["make", "-C", build], tmp_path).stdout
    assert "lagcodegen: generating pend" in out and stamp.stat().st_mtime_ns > before


BUNDLE_USER = """cmake_minimum_required(VERSION 3.20)
project(bundle_user LANGUAGES C)
include(FetchContent)
FetchContent_Declare(pendulum_bundle SOURCE_DIR "{bundle}")
FetchContent_MakeAvailable(pendulum_bundle)
if(TARGET rk4_example OR TARGET cvode_example)
  message(FATAL_ERROR "the bundle built its examples under FetchContent")
endif()
add_executable(main main.c)
target_link_libraries(main PRIVATE pendulum::pendulum)
enable_testing()
"""

INSTALLED_USER = """cmake_minimum_required(VERSION 3.20)
project(installed_user LANGUAGES C)
find_package(pendulum CONFIG REQUIRED)
add_executable(main main.c)
target_link_libraries(main PRIVATE pendulum::pendulum)
"""

MAIN = """#include <stdio.h>
#include "pendulum.h"
int main(void) {
    double y[PENDULUM_NY] = {1.0, 0.0}, p[PENDULUM_NP] = {1.0, 9.81, 1.0}, ydot[PENDULUM_NY];
    int rc = pendulum_rhs(0.0, y, p, ydot);
    printf("%d %.17g\\n", rc, ydot[1]);
    return rc;
}
"""


def bundle(tmp_path) -> Path:
    out = tmp_path / "bundle"
    run([Path(BIN) / "lagcodegen", "generate", EXAMPLES / "pendulum.toml", "-o", out, "--bundle", "-q"], tmp_path)
    return out


def check_main(output: str):
    rc, value = output.split()
    assert rc == "0" and float(value) == pytest.approx(-9.81 * np.sin(1.0), rel=1e-14)


def test_bundle_fetchcontent_install_find_package_and_pkg_config(tmp_path, tools):
    out = bundle(tmp_path)
    (tmp_path / "main.c").write_text(MAIN)
    # FetchContent (add_subdirectory underneath): the library only, no examples, no tests
    user = tmp_path / "user"
    user.mkdir()
    shutil.copy(tmp_path / "main.c", user / "main.c")
    (user / "CMakeLists.txt").write_text(BUNDLE_USER.format(bundle=out))
    run(["cmake", "-S", user, "-B", user / "b", "-G", "Ninja"], tmp_path)
    run(["cmake", "--build", user / "b"], tmp_path)
    check_main(run([user / "b" / "main"], tmp_path).stdout)
    assert "Total Tests: 0" in run(["ctest", "--test-dir", user / "b", "-N"], tmp_path).stdout
    assert not (user / "b" / "_deps").exists() or not list((user / "b").rglob("rk4_example"))

    # top level, position-independent, installed; then found by find_package and by pkg-config
    run(["cmake", "-S", out, "-B", out / "b", "-G", "Ninja", "-DPENDULUM_POSITION_INDEPENDENT_CODE=ON",
         "-DCMAKE_EXPORT_COMPILE_COMMANDS=ON", "-DCMAKE_INSTALL_LIBDIR=lib"], tmp_path)
    run(["cmake", "--build", out / "b"], tmp_path)
    commands = json.loads((out / "b" / "compile_commands.json").read_text())
    assert any("-fPIC" in c["command"] for c in commands if c["file"].endswith("pendulum.c"))
    assert (out / "b" / "rk4_example").exists()  # top level: examples built
    prefix = tmp_path / "prefix"
    run(["cmake", "--install", out / "b", "--prefix", prefix], tmp_path)
    installed = {p.relative_to(prefix).as_posix() for p in prefix.rglob("*") if p.is_file()}
    assert {"include/pendulum.h", "lib/libpendulum.a", "lib/pkgconfig/pendulum.pc",
            "lib/cmake/pendulum/pendulumConfig.cmake", "lib/cmake/pendulum/pendulumTargets.cmake"} <= installed
    finder = tmp_path / "finder"
    finder.mkdir()
    shutil.copy(tmp_path / "main.c", finder / "main.c")
    (finder / "CMakeLists.txt").write_text(INSTALLED_USER)
    run(["cmake", "-S", finder, "-B", finder / "b", "-G", "Ninja", f"-DCMAKE_PREFIX_PATH={prefix}"], tmp_path)
    run(["cmake", "--build", finder / "b"], tmp_path)
    check_main(run([finder / "b" / "main"], tmp_path).stdout)
    # the .pc file is relocatable: move the whole prefix, pkg-config still points into it
    moved = tmp_path / "moved"
    prefix.rename(moved)
    env = {**ENV, "PKG_CONFIG_PATH": str(moved / "lib" / "pkgconfig")}
    flags = run(["pkg-config", "--cflags", "--libs", "pendulum"], tmp_path, env=env).stdout.split()
    assert f"-I{moved}/include" in [os.path.normpath(f) if f.startswith("-I") else f for f in flags] or \
        any(f.startswith("-I") and Path(f[2:]).resolve() == (moved / "include").resolve() for f in flags)
    run(["gcc", "-std=c99", "-o", tmp_path / "pc_main", tmp_path / "main.c", *flags], tmp_path)
    check_main(run([tmp_path / "pc_main"], tmp_path).stdout)


def test_bundle_makefile_install_destdir(tmp_path, tools):
    out = bundle(tmp_path)
    (tmp_path / "main.c").write_text(MAIN)
    assert "-fPIC" in run(["make", "-n", "PIC=1", "libpendulum.a"], out).stdout
    stage = tmp_path / "stage"
    run(["make", "install", "PREFIX=/opt/pendulum", f"DESTDIR={stage}"], out)
    root = stage / "opt" / "pendulum"
    assert (root / "lib" / "libpendulum.a").is_file() and (root / "include" / "pendulum.h").is_file()
    pc = (root / "lib" / "pkgconfig" / "pendulum.pc").read_text()
    assert "libdir=/opt/pendulum/lib" in pc  # the final location, not the staging folder
    env = {**ENV, "PKG_CONFIG_PATH": str(root / "lib" / "pkgconfig"), "PKG_CONFIG_SYSROOT_DIR": str(stage)}
    flags = run(["pkg-config", "--cflags", "--libs", "pendulum"], tmp_path, env=env).stdout.split()
    run(["gcc", "-std=c99", "-o", tmp_path / "main", tmp_path / "main.c", *flags], tmp_path)
    check_main(run([tmp_path / "main"], tmp_path).stdout)
    run(["make", "uninstall", "PREFIX=/opt/pendulum", f"DESTDIR={stage}"], out)
    assert not [p for p in stage.rglob("*") if p.is_file()]


def readme_block(language: str) -> str:
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## lagcodegen as a build step"):]
    return re.search(rf"```{language}\n(.*?)```", section, re.S).group(1)


PENDULUM_MAIN = """#include <stdio.h>
#include "pendulum.h"
int main(void) {
    double y[PENDULUM_NY] = {1.0, 0.0}, p[PENDULUM_NP] = {1.0, 9.81, 1.0}, ydot[PENDULUM_NY];
    int rc = pendulum_rhs(0.0, y, p, ydot);
    printf("%d %.17g\\n", rc, ydot[1]);
    return 0;
}
"""


def snippet_project(path: Path) -> Path:
    path.mkdir()
    shutil.copy(EXAMPLES / "pendulum.toml", path / "pendulum.toml")
    (path / "main.c").write_text(PENDULUM_MAIN)
    return path


def test_readme_make_snippet(tmp_path, tools):
    src = snippet_project(tmp_path / "make")
    (src / "Makefile").write_text(readme_block("make"))
    run(["make"], src)
    check_main(run([src / "main"], src).stdout)
    up_to_date = run(["make", "-q"], src, check=False).returncode == 0
    assert up_to_date or own_files_newer_than(src / "pendulum.stamp")
    assert "pendulum.toml" in (src / "pendulum.d").read_text()
    time.sleep(0.02)
    os.utime(src / "pendulum.toml")
    assert run(["make", "-q"], src, check=False).returncode == 1
    assert "lagcodegen generate" in run(["make"], src).stdout
    up_to_date = run(["make", "-q"], src, check=False).returncode == 0
    assert up_to_date or own_files_newer_than(src / "pendulum.stamp")


def test_readme_meson_snippet(tmp_path, tools):
    meson = shutil.which("meson", path=ENV["PATH"])
    if meson is None:
        pytest.skip("meson is not installed (pip install meson, in the [test] extra)")
    src = snippet_project(tmp_path / "meson")
    (src / "meson.build").write_text(readme_block("meson"))
    run([meson, "setup", src / "b", src], src)
    run(["ninja", "-C", src / "b"], src)
    check_main(run([src / "b" / "main"], src).stdout)
    assert nothing_to_do(src / "b", src)
    time.sleep(0.02)
    os.utime(src / "pendulum.toml")
    again = run(["ninja", "-C", src / "b"], src).stdout
    assert "Generating" in again or "pendulum" in again
    assert nothing_to_do(src / "b", src)


def test_cmake_clean_never_reaches_outside_through_a_tampered_manifest(tmp_path, tools):
    """A generated folder shipped with a manifest that lists ``../../../victim.txt``: configuring
    fails naming the manifest, and CMake's clean target deletes nothing outside the build."""
    src = consumer_project(tmp_path / "src")
    (src / "CMakeLists.txt").write_text(CONSUMER.split("lagcodegen_generate(TARGET pendf")[0]
                                        + "add_executable(main main.c)\ntarget_link_libraries(main PRIVATE pend)\n")
    build = tmp_path / "build"
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    run(["cmake", "-S", src, "-B", build, "-G", "Ninja", f"-Dlagcodegen_DIR={cmake_dir()}"], tmp_path)
    run(["ninja", "-C", build], tmp_path)
    manifest = build / "lagcodegen" / "pend" / "pend.lagcodegen.json"
    record = json.loads(manifest.read_text())
    record["files"]["../../../victim.txt"] = record["files"]["pend.c"]
    manifest.write_text(json.dumps(record))
    configure = run(["cmake", "-S", src, "-B", build, "-G", "Ninja", f"-Dlagcodegen_DIR={cmake_dir()}"], tmp_path,
                    check=False)
    assert configure.returncode != 0
    assert "pend.lagcodegen.json" in configure.stderr and "victim.txt" in configure.stderr
    run(["cmake", "--build", build, "--target", "clean"], tmp_path, check=False)
    assert victim.read_text() == "precious\n"
