"""FMU export (lagcodegen.fmu): the archives validated by FMPy (FMI 2.0 and 3.0), simulated by
FMPy in Model Exchange (its CVODE) and Co-Simulation (the FMU's own Dormand-Prince) against
lagcodegen's simulate(), an input force with a step against the analytic step response of a
damped oscillator, a constrained system in its index-1 form against the constrained simulate(),
the sources built again from the archive alone, strict compiler flags, the command line and the
errors."""

import subprocess
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest

import lagcodegen as lcg
from helpers import STRICT_CFLAGS
from lagcodegen.cli import main
from lagcodegen.errors import ModelError

fmpy = pytest.importorskip("fmpy")
from fmpy.validation import validate_fmu  # noqa: E402

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
#: The unconstrained example model files.
MODELS = ["pendulum", "double_pendulum", "damped_driven_oscillator", "central_potential"]
VERSIONS = [2, 3]
BINARY = {2: "binaries/linux64", 3: "binaries/x86_64-linux"}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """Every example model exported once per FMI version: (name, version) -> path."""
    folder = tmp_path_factory.mktemp("fmus")
    cache = {}

    def get(name: str, version: int) -> Path:
        if (name, version) not in cache:
            cache[name, version] = lcg.export_fmu(EXAMPLES / f"{name}.toml", folder / f"{name}_{version}.fmu",
                                                  fmi_version=version)
        return cache[name, version]
    return get


@pytest.fixture(scope="module")
def references():
    """simulate() of each example model (compiled once), by name: (model file, compiled model)."""
    cache = {}

    def get(name: str):
        if name not in cache:
            mf = lcg.modelfile.load_model(EXAMPLES / f"{name}.toml")
            cache[name] = (mf, lcg.compile_file(mf))
        return cache[name]
    return get


def reference(mf, cm, t):
    q0, v0 = mf.initial_state()
    params = {k: v for k, v in mf.simulation.parameters.items() if k in cm.param_names}
    return cm.simulate(t, q0=q0, v0=v0, rtol=1e-12, atol=1e-14, params=params)


def worst(result, ref, t, names) -> tuple[str, float]:
    """The variable of ``names`` farthest from the reference, and that distance relative to the
    variable's largest magnitude over the run."""
    errs = {n: float(np.max(np.abs(np.interp(t, result["time"], result[n]) - ref[n])) / np.max(np.abs(ref[n])))
            for n in names}
    name = max(errs, key=errs.get)
    return name, errs[name]


# ---------------------------------------------------------------------- the archive
@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("name", MODELS)
def test_fmpy_finds_no_problem(fmus, name, version):
    path = fmus(name, version)
    assert validate_fmu(str(path)) == []
    with zipfile.ZipFile(path) as zf:
        files = set(zf.namelist())
    assert f"{BINARY[version]}/{name}.so" in files
    assert f"sources/{name}.c" in files and "sources/lcg_fmu_model.c" in files
    assert ("sources/buildDescription.xml" in files) == (version == 3)


@pytest.mark.parametrize("version", VERSIONS)
def test_model_description_states_the_model(fmus, version):
    """Names as in simulate()'s CSV, start values from the file's initial state, parameters
    tunable (the file keeps every one at run time), outputs as the file asks, and the
    dependencies: der(q) on q_dot alone, der(q_dot) on the states of the Jacobian pattern."""
    md = fmpy.read_model_description(str(fmus("double_pendulum", version)))
    assert md.modelExchange is not None and md.coSimulation is not None
    by_name = {v.name: v for v in md.modelVariables}
    states = ["theta1", "theta2", "theta1_dot", "theta2_dot"]
    assert [v.name for v in md.modelVariables if v.causality == "local" and v.derivative is None] == states
    assert [float(by_name[s].start) for s in states] == [1.0, 0.5, 0.0, 0.0]
    assert [v.name for v in md.modelVariables if v.causality == "output"] == ["energy", "bob1_x", "bob1_y",
                                                                           "bob2_x", "bob2_y"]
    assert {v.name: v.variability for v in md.modelVariables if v.causality == "parameter"} == \
        {"l1": "tunable", "l2": "tunable", "m1": "tunable", "m2": "tunable", "g": "tunable"}
    deps = {u.variable.name: sorted(d.name for d in u.dependencies) for u in md.derivatives}
    assert deps["der(theta1)"] == ["theta1_dot"]
    assert deps["der(theta1_dot)"] == sorted(states)
    outs = {u.variable.name: sorted(d.name for d in u.dependencies) for u in md.outputs}
    assert outs["bob1_x"] == ["theta1"] and outs["bob2_y"] == ["theta1", "theta2"]


def test_fixed_parameters_and_start_values(tmp_path):
    """The file's runtime_parameters are the tunable parameters, the others fixed; the file's
    [simulation] parameters are start values."""
    md = fmpy.read_model_description(str(lcg.export_fmu(EXAMPLES / "damped_driven_oscillator.toml",
                                                          tmp_path / "d.fmu", values={"k": 9.0})))
    params = {v.name: (v.variability, float(v.start)) for v in md.modelVariables if v.causality == "parameter"}
    assert params == {"m": ("fixed", 1.0), "k": ("fixed", 9.0), "c": ("tunable", 0.4), "F0": ("tunable", 1.0),
                      "w": ("tunable", 1.5)}


@pytest.mark.parametrize("version", VERSIONS)
def test_non_ascii_names_make_a_valid_fmu(tmp_path, version):
    """A coordinate, parameter or output named outside ASCII (a joint 'θ') is no name of FMI's
    "structured" convention (its grammar has no such character, not even quoted): the FMU declares
    the "flat" convention, FMPy finds no problem, and the names stay those of simulate()."""
    import sympy as sp
    m = lcg.Model("pend")
    th, = m.coordinates("θ")
    g = m.parameter("ğ", 9.81)
    m.unit("θ", "rad")
    m.particle("bob", 1, (sp.sin(th), -sp.cos(th)))
    m.gravity(g)
    m.output("Ω", 2 * th)
    path = lcg.export_fmu(m, tmp_path / "u.fmu", fmi_version=version, outputs=["Ω"], initial={"θ": 0.3})
    assert validate_fmu(str(path)) == []  # 8 problems before
    md = fmpy.read_model_description(str(path))
    assert md.variableNamingConvention == "flat"
    assert [v.name for v in md.modelVariables] == ["time", "θ", "θ_dot", "der(θ)", "der(θ_dot)", "ğ", "Ω"]
    res = fmpy.simulate_fmu(str(path), stop_time=1.0, start_values={"ğ": 1.0})
    ref = lcg.compile_model(m, outputs=["Ω"]).simulate([0, 1.0], q0=[0.3], params={"ğ": 1.0})
    assert abs(res["Ω"][-1] - ref["Ω"][-1]) < 1e-5
    # plain names keep the structured convention
    md = fmpy.read_model_description(str(lcg.export_fmu(lcg.systems.pendulum(), tmp_path / "p.fmu",
                                                        fmi_version=version)))
    assert md.variableNamingConvention == "structured"


# ---------------------------------------------------------------------- trajectories
@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("name", MODELS)
def test_co_simulation_agrees_with_simulate(fmus, references, name, version):
    """Co-Simulation at a communication step of 1 ms, tolerance 1e-8: states and outputs within
    1e-6 of simulate() (relative to each variable's range) over 10 s."""
    mf, cm = references(name)
    t = np.linspace(0.0, 10.0, 201)
    ref = reference(mf, cm, t)
    names = ref.state_names + list(cm.output_names)
    res = fmpy.simulate_fmu(str(fmus(name, version)), fmi_type="CoSimulation", stop_time=10.0,
                            output_interval=1e-3, relative_tolerance=1e-8, output=names)
    assert res["time"][-1] == pytest.approx(10.0)
    var, err = worst(res, ref, t, names)
    assert err < 1e-6, f"{var}: {err:.2e}"


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("name", MODELS)
def test_model_exchange_agrees_with_simulate(fmus, references, name, version):
    """FMPy's CVODE (BDF, absolute tolerance = relative tolerance) on the FMU's derivatives: within
    1e-6 at rtol 1e-8 over 2 s, and converging onto simulate() as the tolerance shrinks (rtol
    1e-10: within 2e-7 over 10 s; the difference is the importer's integrator)."""
    mf, cm = references(name)
    for t_end, rtol, bound in ((2.0, 1e-8, 1e-6), (10.0, 1e-10, 2e-7)):
        t = np.linspace(0.0, t_end, 201)
        ref = reference(mf, cm, t)
        names = ref.state_names + list(cm.output_names)
        res = fmpy.simulate_fmu(str(fmus(name, version)), fmi_type="ModelExchange", solver="CVode",
                                stop_time=t_end, output_interval=t_end / 1000, relative_tolerance=rtol,
                                output=names)
        var, err = worst(res, ref, t, names)
        assert err < bound, f"rtol {rtol:g}, {var}: {err:.2e}"


def test_co_simulation_follows_the_importers_tolerance(fmus, references):
    """The embedded Dormand-Prince steps to the tolerance the importer sets (fmi2SetupExperiment /
    fmi3EnterInitializationMode): over long communication steps (0.5 s) the error against
    simulate() shrinks with the tolerance and stays near it."""
    mf, cm = references("double_pendulum")
    t = np.linspace(0.0, 5.0, 11)
    ref = reference(mf, cm, t)
    errors = []
    for rtol in (1e-4, 1e-7, 1e-10):
        res = fmpy.simulate_fmu(str(fmus("double_pendulum", 2)), fmi_type="CoSimulation", stop_time=5.0,
                                output_interval=0.5, relative_tolerance=rtol, output=["theta1", "theta2"])
        errors.append(worst(res, ref, t, ["theta1", "theta2"])[1])
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 1e-7 and errors[0] < 1e-1


def test_start_values_and_parameters_set_by_the_importer(fmus, references):
    """FMPy's start_values reach the states and parameters (set before initialization)."""
    mf, cm = references("pendulum")
    t = np.linspace(0.0, 3.0, 61)
    ref = cm.simulate(t, q0=[0.3], v0=[0.2], params={"g": 1.62}, rtol=1e-12, atol=1e-14)
    res = fmpy.simulate_fmu(str(fmus("pendulum", 3)), fmi_type="CoSimulation", stop_time=3.0, output_interval=1e-3,
                            relative_tolerance=1e-9, start_values={"theta": 0.3, "theta_dot": 0.2, "g": 1.62},
                            output=["theta", "theta_dot"])
    var, err = worst(res, ref, t, ["theta", "theta_dot"])
    assert err < 1e-6, f"{var}: {err:.2e}"


# ---------------------------------------------------------------------- inputs
FORCED = """
[model]
name = "forced_oscillator"
coordinates = ["x"]

[parameters]
m = 2.0
k = 8.0
c = 0.8

[inputs]
F = 0.0

[[points]]
name = "wall"
position = [0, 0]

[[particles]]
name = "mass"
mass = "m"
position = ["x", 0]

[[springs]]
a = "mass"
b = "wall"
k = "k"

[[dampers]]
point = "mass"
c = "c"

[[generalized_forces]]
coordinate = "x"
expr = "F"

[outputs]
force = "F"

[simulation]
outputs = ["energy", "force"]
"""
M, K, C, F0, T_STEP, T_END = 2.0, 8.0, 0.8, 3.0, 1.0, 10.0


def step_response(t):
    """m x'' + c x' + k x = F0 H(t - t1) from rest at 0 (underdamped): the textbook solution."""
    w0 = np.sqrt(K / M)
    zeta = C / (2 * np.sqrt(K * M))
    wd = w0 * np.sqrt(1 - zeta ** 2)
    s = np.clip(t - T_STEP, 0.0, None)
    x = F0 / K * (1 - np.exp(-zeta * w0 * s) * (np.cos(wd * s) + zeta / np.sqrt(1 - zeta ** 2) * np.sin(wd * s)))
    return np.where(t >= T_STEP, x, 0.0)


@pytest.mark.parametrize("version", VERSIONS)
def test_input_step_agrees_with_the_analytic_response(tmp_path, version):
    mf = lcg.modelfile.loads_model(FORCED, "forced_oscillator.toml")
    path = lcg.export_fmu(mf, tmp_path / "forced.fmu", fmi_version=version)
    assert validate_fmu(str(path)) == []
    md = fmpy.read_model_description(str(path))
    inputs = [v for v in md.modelVariables if v.causality == "input"]
    assert [(v.name, float(v.start), v.variability) for v in inputs] == [("F", 0.0, "continuous")]
    deps = {u.variable.name: sorted(d.name for d in u.dependencies) for u in md.derivatives}
    assert deps["der(x_dot)"] == ["F", "x", "x_dot"]
    assert {u.variable.name: [d.name for d in u.dependencies] for u in md.outputs}["force"] == ["F"]
    signal = np.array([(0.0, 0.0), (T_STEP, 0.0), (T_STEP, F0), (T_END, F0)], dtype=[("time", float), ("F", float)])
    for kind in ("ModelExchange", "CoSimulation"):
        res = fmpy.simulate_fmu(str(path), fmi_type=kind, stop_time=T_END, output_interval=1e-3,
                                relative_tolerance=1e-8, input=signal, output=["x", "force"])
        err = np.max(np.abs(res["x"] - step_response(res["time"]))) / (F0 / K)
        assert err < 2e-6, f"{kind}: {err:.2e}"
        after = res["time"] > T_STEP + 1e-9  # FMPy interpolates the table linearly: F0 to rounding
        assert np.allclose(res["force"][after], F0, rtol=1e-14) and np.all(res["force"][res["time"] < T_STEP] == 0)


def test_input_stays_an_input_when_the_file_folds_parameters(tmp_path):
    """runtime_parameters = [] folds every parameter in simulate(); the FMU keeps them all in p,
    fixed, and the input an input."""
    mf = lcg.modelfile.loads_model(FORCED.replace("[simulation]", "[simulation]\nruntime_parameters = []"))
    md = fmpy.read_model_description(str(lcg.export_fmu(mf, tmp_path / "f.fmu", fmi_version=3)))
    kinds = {v.name: (v.causality, v.variability) for v in md.modelVariables if v.name in ("m", "k", "c", "F")}
    assert kinds == {"m": ("parameter", "fixed"), "k": ("parameter", "fixed"), "c": ("parameter", "fixed"),
                     "F": ("input", "continuous")}


# ---------------------------------------------------------------------- constrained systems
@pytest.mark.parametrize("version", VERSIONS)
def test_constrained_system_exports_its_index1_form(tmp_path, version):
    """The Cartesian pendulum (x^2 + y^2 = l^2) as the index-1 ODE with the file's Baumgarte rates
    (5, 5): FMPy finds no problem; Co-Simulation (10 s) and Model Exchange (2 s, rtol 1e-8) agree
    with the constrained simulate() (native CVODE on the same index-1 form) to 1e-6, multiplier
    and tension included; the constraint residuals stay at the level of the integration error."""
    mf = lcg.modelfile.load_model(EXAMPLES / "cartesian_pendulum.toml")
    path = lcg.export_fmu(mf, tmp_path / "cp.fmu", fmi_version=version)
    assert validate_fmu(str(path)) == []
    md = fmpy.read_model_description(str(path))
    variables = {v.name: v for v in md.modelVariables}
    assert [(n, variables[n].variability, float(variables[n].start)) for n in ("baumgarte_alpha", "baumgarte_beta")] \
        == [("baumgarte_alpha", "fixed", 5.0), ("baumgarte_beta", "fixed", 5.0)]
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    assert outputs == ["energy", "tension", "bob_x", "bob_y", "lambda_0", "g_0", "gdot_0"]
    cm = lcg.compile_file(mf)
    q0, v0 = mf.initial_state()
    compared = ["x", "y", "x_dot", "y_dot", "energy", "tension", "lambda_0"]
    for kind, t_end, options, drift in (("CoSimulation", 10.0, {}, 1e-8),
                                        ("ModelExchange", 2.0, dict(solver="CVode"), 1e-6)):
        t = np.linspace(0.0, t_end, 201)
        ref = cm.simulate(t, q0=q0, v0=v0, rtol=1e-12, atol=1e-14)
        res = fmpy.simulate_fmu(str(path), fmi_type=kind, stop_time=t_end, output_interval=1e-3,
                                relative_tolerance=1e-8, output=compared + ["g_0", "gdot_0"], **options)
        var, err = worst(res, ref, t, compared)
        assert err < 1e-6, f"{kind}, {var}: {err:.2e}"
        assert np.max(np.abs(res["g_0"])) < drift and np.max(np.abs(res["gdot_0"])) < 10 * drift, kind


def test_constrained_auto_stabilization_takes_the_natural_rate(tmp_path):
    """baumgarte="auto" exports alpha = beta = -1 (the natural rate at the initial state, computed
    when initialization ends), as the native driver does at each run's start: Co-Simulation agrees
    with simulate(baumgarte="auto") from a drifted initial state (where the rates matter)."""
    mf = lcg.modelfile.load_model(EXAMPLES / "cartesian_pendulum.toml")
    path = lcg.export_fmu(mf, tmp_path / "cp.fmu", fmi_version=3, baumgarte="auto")
    md = fmpy.read_model_description(str(path))
    assert {v.name: float(v.start) for v in md.modelVariables if v.name.startswith("baumgarte")} == \
        {"baumgarte_alpha": -1.0, "baumgarte_beta": -1.0}
    cm = lcg.compile_file(mf)
    q0 = [np.sin(1.0) * 1.01, -np.cos(1.0) * 1.01]  # 1 % off the circle: the stabilization pulls it back
    t = np.linspace(0.0, 3.0, 121)
    ref = cm.simulate(t, q0=q0, v0=[0.0, 0.0], baumgarte="auto", initial="none", rtol=1e-12, atol=1e-14)
    res = fmpy.simulate_fmu(str(path), fmi_type="CoSimulation", stop_time=3.0, output_interval=1e-3,
                            relative_tolerance=1e-10, start_values={"x": q0[0], "y": q0[1]}, output=["x", "y", "g_0"])
    var, err = worst(res, ref, t, ["x", "y"])
    assert err < 1e-6, f"{var}: {err:.2e}"
    assert abs(res["g_0"][0]) > 1e-2 and abs(res["g_0"][-1]) < 1e-4  # the drift decays


# ---------------------------------------------------------------------- sources
@pytest.mark.parametrize("version", VERSIONS)
def test_sources_build_the_fmu_again(fmus, tmp_path, cc, version):
    """The files the archive lists (FMI 2.0: SourceFiles; FMI 3.0: buildDescription.xml), compiled
    alone with strict flags, give a binary that FMPy runs to the same numbers."""
    path = fmus("double_pendulum", version)
    unzipped = tmp_path / "fmu"
    with zipfile.ZipFile(path) as zf:
        zf.extractall(unzipped)
    if version == 2:
        root = ET.parse(unzipped / "modelDescription.xml").getroot()
        listed = [f.get("name") for f in root.find("CoSimulation").find("SourceFiles")]
    else:
        root = ET.parse(unzipped / "sources" / "buildDescription.xml").getroot()
        listed = [f.get("name") for f in root.iter("SourceFile")]
    binary = next((unzipped / BINARY[version]).iterdir())
    original = fmpy.simulate_fmu(str(path), fmi_type="CoSimulation", stop_time=1.0, output_interval=1e-3,
                                 output=["theta1", "theta2_dot"])
    binary.unlink()
    subprocess.run([cc, *STRICT_CFLAGS, "-O2", "-fPIC", "-shared", *listed, "-o", str(binary), "-lm"],
                   cwd=unzipped / "sources", check=True, capture_output=True)
    rebuilt = fmpy.simulate_fmu(str(unzipped), fmi_type="CoSimulation", stop_time=1.0, output_interval=1e-3,
                                output=["theta1", "theta2_dot"])
    assert np.allclose(rebuilt["theta1"], original["theta1"], rtol=1e-12, atol=1e-14)
    assert np.allclose(rebuilt["theta2_dot"], original["theta2_dot"], rtol=1e-12, atol=1e-14)


# ---------------------------------------------------------------------- command line and errors
def test_command_line_writes_the_fmu(tmp_path):
    out = tmp_path / "p.fmu"
    assert main(["generate", str(EXAMPLES / "pendulum.toml"), "--fmu", str(out), "--fmi", "3", "--set", "g=1.62",
                 "-q"]) == 0
    assert validate_fmu(str(out)) == []
    md = fmpy.read_model_description(str(out))
    assert md.fmiVersion == "3.0"
    assert float({v.name: v for v in md.modelVariables}["g"].start) == 1.62
    assert main(["generate", str(EXAMPLES / "pendulum.toml"), "-q"]) == 2  # neither -o nor --fmu
    assert main(["generate", str(EXAMPLES / "pendulum.toml"), "--fmu", str(out), "--bundle", "-q"]) == 2


def test_errors_name_the_problem(tmp_path):
    with pytest.raises(ModelError, match="fmi_version must be 2 or 3"):
        lcg.export_fmu(EXAMPLES / "pendulum.toml", tmp_path / "x.fmu", fmi_version=4)
    with pytest.raises(ModelError, match="tunable parameter 'q' is not a parameter"):
        lcg.export_fmu(EXAMPLES / "pendulum.toml", tmp_path / "x.fmu", tunable=["q"])
    with pytest.raises(ModelError, match="'phi', which is not a coordinate"):
        lcg.export_fmu(EXAMPLES / "pendulum.toml", tmp_path / "x.fmu", initial={"phi": 1.0})
    with pytest.raises(ModelError, match="events and inequality constraints need event indicators"):
        lcg.export_fmu(EXAMPLES / "sliding_off_sphere.toml", tmp_path / "x.fmu")
    with pytest.raises(ModelError, match="baumgarte must be 'auto' or"):
        lcg.export_fmu(EXAMPLES / "cartesian_pendulum.toml", tmp_path / "x.fmu", baumgarte="fast")
    model = lcg.systems.pendulum()
    model.output("time", model.t)
    with pytest.raises(ModelError, match="'time' is both"):
        lcg.export_fmu(model, tmp_path / "x.fmu", outputs=["time"])
    with pytest.raises(ModelError, match="name of one of the FMU's own files"):
        lcg.export_fmu(lcg.systems.pendulum(), tmp_path / "x.fmu", model_identifier="lcg_dopri")
    assert not (tmp_path / "x.fmu").exists()


def test_strict_flags_on_every_source(fmus, tmp_path, cc):
    """Every C file of both versions' archives (an unconstrained and a constrained model) compiles
    with -Wall -Wextra -Werror -std=c99 -pedantic."""
    for name in ("damped_driven_oscillator", "cartesian_pendulum"):
        for version in VERSIONS:
            folder = tmp_path / f"{name}{version}"
            with zipfile.ZipFile(fmus(name, version)) as zf:
                zf.extractall(folder)
            sources = folder / "sources"
            assert "lcg_fmu_model.c" in [f.name for f in sources.glob("*.c")]
            for c_file in sorted(sources.glob("*.c")):
                proc = subprocess.run([cc, *STRICT_CFLAGS, "-c", c_file.name, "-o", "/dev/null"], cwd=sources,
                                      capture_output=True, text=True)
                assert proc.returncode == 0, f"{name}, FMI {version}, {c_file.name}:\n{proc.stderr}"


@pytest.mark.parametrize("version", VERSIONS)
def test_a_nan_communication_step_is_called_nan_not_negative(fmus, tmp_path, version):
    """fmiDoStep with a NaN step size: refused, the message saying NaN (before: "negative"); a
    negative step still says negative."""
    from fmpy import extract, read_model_description
    path = fmus("pendulum", version)
    md = read_model_description(str(path))
    folder = extract(str(path), unzipdir=str(tmp_path / "unzipped"))
    messages = []
    if version == 2:
        from ctypes import byref
        from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, \
            fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, calloc, free
        from fmpy.logging import addLoggerProxy
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(lambda env, name, status, category, message:
                                                  messages.append(message.decode()))
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(byref(callbacks))
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
                        instanceName="nan")
        fmu.instantiate(callbacks=callbacks)
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
    else:
        from fmpy.fmi3 import FMU3Slave
        fmu = FMU3Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
                        instanceName="nan")
        fmu.instantiate(logMessage=lambda env, status, category, message: messages.append(message.decode()))
        fmu.enterInitializationMode(startTime=0.0)
        fmu.exitInitializationMode()
    for step, word in ((float("nan"), "not a number (NaN)"), (-0.1, "negative"), (float("inf"), "infinite")):
        messages.clear()
        with pytest.raises(Exception):
            fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=step)
        assert any(f"DoStep: the communication step size is {word}" in m for m in messages), (step, messages)
    fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.1)  # a good step still works
    fmu.terminate()
    fmu.freeInstance()



@pytest.mark.parametrize("version", VERSIONS)
def test_a_quaternion_body_exports_its_nq_plus_nv_states(tmp_path, version):
    """A free body on a quaternion ball joint: the FMU's states are q (4) and the angular
    velocity (3), FMPy finds no problem, and Co-Simulation and Model Exchange follow simulate()."""
    m = lcg.Model("top")
    m.link("body", joint=lcg.Joint.spherical("ball"), mass=1.0, inertia=(1.0, 2.0, 3.0))
    initial = {"ball_wx": 0.01, "ball_wy": 2.0, "ball_wz": 0.01}
    path = lcg.export_fmu(m, tmp_path / "top.fmu", fmi_version=version, initial=initial)
    assert validate_fmu(str(path)) == []
    md = fmpy.read_model_description(str(path))
    states = [v.name for v in md.modelVariables if v.name.startswith("ball_")]
    assert states == ["ball_qx", "ball_qy", "ball_qz", "ball_qw", "ball_wx", "ball_wy", "ball_wz"]
    ref = lcg.compile_model(m).simulate(np.linspace(0, 3, 4), v0=[0.01, 2.0, 0.01], rtol=1e-11, atol=1e-12)
    for kind, extra in [("CoSimulation", {}), ("ModelExchange", {"solver": "CVode"})]:
        res = fmpy.simulate_fmu(str(path), fmi_type=kind, stop_time=3.0, output_interval=1e-3, relative_tolerance=1e-9,
                                output=states, **extra)
        got = np.array([res[s][-1] for s in states])
        assert np.abs(got - ref.y[-1]).max() < 1e-6, kind
