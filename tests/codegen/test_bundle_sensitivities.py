"""Bundles with the forward sensitivity functions (render_bundle(..., sensitivities=True),
generate --bundle --sensitivities): built with make (strict flags) and CMake, the shipped RK4
example of the state and its sensitivities against lagcodegen's CVODE sensitivities, the
prototypes in the bundle's header."""

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen import ModelError, Scene, derive, generate_c, systems, write_bundle

from helpers import STRICT_CFLAGS

ROOT = Path(__file__).resolve().parents[2]
Y0 = [1.0, 0.5, 0.0, 0.0]
T_END = 2.0


@pytest.fixture(scope="module")
def scene():
    return Scene(derive(systems.double_pendulum()), outputs=["energy"], runtime_parameters=["g", "m1"],
                 values={"l2": 0.7})


def run(cmd, cwd):
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{proc.stdout}\n{proc.stderr}"
    return proc


def table(text):
    rows = list(csv.reader(text.splitlines()))
    return rows[0], np.array([float(v) for v in rows[-1]])


def test_bundle_with_sensitivities_builds_and_matches_cvode(tmp_path, tools, scene):
    paths = write_bundle(scene, tmp_path, y0=Y0, t_end=T_END, sensitivities=True)
    names = {p.name for p in paths}
    assert {"double_pendulum_sens.c", "sens_example.c"} <= names
    header = (tmp_path / "double_pendulum.h").read_text()
    assert "int double_pendulum_sens_rhs(double t, const double *y, const double *p, int ns, const int *which, " \
           "const double *s, double *ydot, double *sdot);" in header
    assert "int double_pendulum_sens_outputs(" in header
    assert header.index("double_pendulum_sens_rhs") < header.rindex("#ifdef __cplusplus")
    readme = (tmp_path / "README.md").read_text()
    assert "## Sensitivities" in readme and "double_pendulum_sens.c" in readme

    # make with the strict flags: the library holds the sensitivity functions, make check runs the example
    run(["make", f"CFLAGS={' '.join(STRICT_CFLAGS)} -O2", "check"], tmp_path)
    nm = run(["nm", "libdouble_pendulum.a"], tmp_path).stdout
    assert "T double_pendulum_sens_rhs" in nm and "T double_pendulum_sens_outputs" in nm
    head, final = table((tmp_path / "sens_example.csv").read_text())
    states = ["theta1", "theta2", "theta1_dot", "theta2_dot"]
    directions = ["g", "m1"] + [f"{s}(0)" for s in states]
    assert head == ["t", *states, *(f"d{s}/d{d}" for d in directions for s in states)]
    assert final[0] == T_END

    # lagcodegen's CVODE sensitivities of the same model and parameters
    cm = lcg.build_code(generate_c(scene))
    ref = cm.simulate([0.0, T_END], y0=Y0, rtol=1e-11, atol=1e-13, sensitivities=directions)
    np.testing.assert_allclose(final[1:5], ref.y[-1], rtol=0, atol=1e-7)
    got = final[5:].reshape(len(directions), 4)
    want = ref.sensitivities[-1, :, :4]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6 * np.max(np.abs(want)))

    # CMake builds the same library and example
    run(["cmake", "-S", ".", "-B", "build"], tmp_path)
    run(["cmake", "--build", "build"], tmp_path)
    proc = run([str(tmp_path / "build" / "sens_example"), "-e", "1000000"], tmp_path)
    _, final_cmake = table(proc.stdout)
    np.testing.assert_allclose(final_cmake, final, rtol=0, atol=1e-12)
    assert len(proc.stdout.splitlines()) == 3  # header, t0, t_end


def test_sens_rhs_against_differences_of_the_bundles_rhs(tmp_path, tools, scene):
    """sdot of a parameter direction with s = 0 is df/dp: against central differences of the
    bundle's own <prefix>_rhs, called from a C program linked to the library."""
    write_bundle(scene, tmp_path, y0=Y0, t_end=T_END, sensitivities=True)
    (tmp_path / "probe.c").write_text("""
#include <stdio.h>
#include "double_pendulum.h"
int main(void)
{
    const double y[4] = {0.3, -0.8, 0.4, 1.1};
    double p[2] = {9.81, 1.5}, s[8] = {0}, ydot[4], sdot[8], fp[4], fm[4];
    const int which[2] = {0, 1};
    int j, i;
    if (double_pendulum_sens_rhs(0.0, y, p, 2, which, s, ydot, sdot) != 0)
        return 1;
    for (j = 0; j < 2; ++j) {
        const double h = 1e-6 * p[j], p0 = p[j];
        p[j] = p0 + h;
        double_pendulum_rhs(0.0, y, p, fp);
        p[j] = p0 - h;
        double_pendulum_rhs(0.0, y, p, fm);
        p[j] = p0;
        for (i = 0; i < 4; ++i)
            printf("%.17g %.17g\\n", sdot[j * 4 + i], (fp[i] - fm[i]) / (2 * h));
    }
    return 0;
}
""")
    run(["make", "libdouble_pendulum.a"], tmp_path)
    run(["gcc", *STRICT_CFLAGS, "-O2", "probe.c", "libdouble_pendulum.a", "-lm", "-o", "probe"], tmp_path)
    pairs = np.array([[float(v) for v in line.split()] for line in run(["./probe"], tmp_path).stdout.splitlines()])
    assert np.max(np.abs(pairs[:, 0])) > 0.1  # the parameters move the accelerations
    np.testing.assert_allclose(pairs[:, 0], pairs[:, 1], rtol=1e-7, atol=1e-8)


def test_refusals_and_default_unchanged(tmp_path, scene):
    with pytest.raises(ModelError, match="sensitivity functions are C"):
        lcg.render_bundle(scene, "fortran", sensitivities=True)
    plain = lcg.render_bundle(scene)
    with_sens = lcg.render_bundle(scene, sensitivities=True)
    assert "double_pendulum_sens.c" not in plain and "sens_example" not in plain["Makefile"]
    # only the header, the build files and the README gain anything; the model source is the same
    assert with_sens["double_pendulum.c"] == plain["double_pendulum.c"]
    assert with_sens["double_pendulum.h"].startswith(plain["double_pendulum.h"][:plain["double_pendulum.h"].rindex(
        "#ifdef __cplusplus")])


def test_generate_bundle_sensitivities_from_the_command_line(tmp_path):
    model = ROOT / "examples" / "double_pendulum.toml"
    out = tmp_path / "b"
    cmd = [sys.executable, "-m", "lagcodegen", "generate", str(model), "-o", str(out), "--bundle", "--sensitivities",
           "-q"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    prefix = next(p.name[:-len("_sens.c")] for p in out.glob("*_sens.c"))
    assert f"{prefix}_sens_rhs" in (out / f"{prefix}.h").read_text() and (out / "sens_example.c").is_file()
    again = subprocess.run(cmd[:-1] + ["--check", "-q"], capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    bad = subprocess.run(cmd[:-3] + ["--sensitivities"], capture_output=True, text=True, timeout=300)
    assert bad.returncode != 0 and "--bundle" in bad.stderr
