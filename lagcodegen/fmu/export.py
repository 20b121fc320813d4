"""Export a model as an FMU (FMI 2.0 or 3.0, Model Exchange and Co-Simulation in one archive):
one job, from a model (or model file) to the zip file: derivation, the scene with every
parameter in ``p``, the generated C (:func:`lagcodegen.codegen.generate_code`, as it is), the
model table ``lcg_fmu_model.c``, the model-independent FMU core and FMI functions
(``templates/fmu``), the standard's headers (``include/``), modelDescription.xml
(:mod:`.description`), the compiled binary for this platform and the sources.
"""

from __future__ import annotations

import hashlib
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import zipfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Mapping, Sequence

from ..build import compiler_id
from ..cache import CACHE_FORMAT, cache_key, cached_build
from ..codegen.constrained import generate_constrained
from ..codegen.languages import generate_code
from ..codegen.templates import environment, templates_dir
from ..derivation import derive
from ..errors import CompileError, LagcodegenError, ModelError
from ..formulation.scene import Scene
from ..model.model import Model
from ..modelfile.document import ModelFile, constrained_outputs
from ..modelfile.loader import load_model
from ..theory.constraints import ConstrainedSystem
from ..util import BAUMGARTE_AUTO, check_baumgarte, check_finite, excerpt, fmu_path_problem
from ..version import __version__
from .description import Header, build_description_fmi3, model_description_fmi2, model_description_fmi3
from .variables import VariableTable, build_table, variable_table

FMI_VERSIONS = (2, 3)
#: The model-independent C of every FMU (templates/fmu), and the FMI version's own functions.
CORE_FILES = ("lcg_fmu.h", "lcg_fmu_core.c", "lcg_dopri.h", "lcg_dopri.c")
FMI_FILES = {2: ("lcg_fmi2.c",), 3: ("lcg_fmi3.c",)}
#: The standard's headers (lagcodegen/fmu/include/fmi<version>, BSD 2-clause, unchanged).
FMI_HEADERS = {2: ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"),
               3: ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")}
MODEL_TABLE = "lcg_fmu_model.c"
#: Flags of the binary (the sources are C99 + libm; only the FMI functions are exported).
FMU_CFLAGS = ("-std=c99", "-O2", "-fPIC", "-fvisibility=hidden")
#: Relative tolerance of the Co-Simulation integrator when neither the call nor the file gives one
#: (the importer's tolerance, fmi2SetupExperiment / fmi3EnterInitializationMode, replaces it).
DEFAULT_TOLERANCE = 1e-8
INCLUDE_DIR = Path(__file__).resolve().parent / "include"


def _binary_folder(fmi_version: int) -> tuple[str, str]:
    """(platform folder, library suffix) of this machine's binary."""
    system, machine = sys.platform, platform.machine().lower()
    arch = {"amd64": "x86_64", "x86_64": "x86_64", "arm64": "aarch64", "aarch64": "aarch64"}.get(machine)
    if system.startswith("linux") and arch:
        return ("linux64" if arch == "x86_64" and fmi_version == 2 else f"{arch}-linux"), ".so"
    if system == "darwin" and arch:
        return ("darwin64" if fmi_version == 2 else f"{arch}-darwin"), ".dylib"
    raise ModelError(f"export_fmu: no FMI platform name known for {system} on {machine} (Linux and macOS on "
                     "x86_64 or aarch64 are)")


def _model_file(source) -> ModelFile | None:
    if isinstance(source, ModelFile):
        return source
    if isinstance(source, (str, os.PathLike)):
        return load_model(source)
    return None


def _token(texts: Sequence[str]) -> str:
    """A GUID-shaped digest of the FMU's content: the same sources give the same token."""
    h = hashlib.sha256("\0".join(texts).encode()).hexdigest()
    return f"{{{h[:8]}-{h[8:12]}-{h[12:16]}-{h[16:20]}-{h[20:32]}}}"


def _check_names(table: VariableTable) -> None:
    seen: dict[str, str] = {}
    for v in table.variables:
        if v.name in seen:
            raise ModelError(f"export_fmu: the name {v.name!r} is both a {seen[v.name]} and a {v.kind} of the FMU: "
                             "FMU variable names must be unique (rename the output or coordinate)")
        seen[v.name] = v.kind


def _run(cmd: list[str], folder: Path, what: str) -> None:
    try:
        proc = subprocess.run(cmd, cwd=folder, capture_output=True, text=True)
    except OSError as exc:
        raise CompileError(f"export_fmu: cannot run the C compiler {cmd[0]!r}: {exc}", cmd, "") from None
    if proc.returncode != 0:
        raise CompileError(f"export_fmu: the C compiler failed on {what}", cmd, proc.stdout + proc.stderr)


def runtime_files(fmi_version: int) -> dict[str, str]:
    """The model-independent C of an FMI version's FMUs (core, integrator, FMI functions, the
    standard's headers): file name -> text."""
    folder = templates_dir() / "fmu"
    files = {name: (folder / name).read_text() for name in (*CORE_FILES, *FMI_FILES[fmi_version])}
    files.update({name: (INCLUDE_DIR / f"fmi{fmi_version}" / name).read_text() for name in FMI_HEADERS[fmi_version]})
    return files


def runtime_object(fmi_version: int, cc: str) -> Path:
    """The model-independent part of an FMI version's binaries compiled once per lagcodegen
    version, compiler and sources into one relocatable object (``cc -r``), kept in the build cache
    (:mod:`lagcodegen.cache`): an export then compiles only the model's C (the runtime is 80-90%
    of the compiler's time for a double pendulum)."""
    files = runtime_files(fmi_version)
    key = cache_key([__version__, f"cache format {CACHE_FORMAT}", f"fmu runtime fmi{fmi_version}", compiler_id(cc),
                     " ".join(FMU_CFLAGS), *sorted(f"{k}\0{v}" for k, v in files.items())])
    filename = f"lcg_fmu_fmi{fmi_version}.o"

    def make(tmp: Path) -> Path:
        for name, text in files.items():
            (tmp / name).write_text(text)
        c_files = sorted(n for n in files if n.endswith(".c"))
        # one compiler per file, all at once (the runtime's files are independent): on two cores
        # about half the time of one after the other
        with ThreadPoolExecutor(max_workers=max(1, min(len(c_files), os.cpu_count() or 1))) as pool:
            list(pool.map(lambda name: _run([cc, *FMU_CFLAGS, "-c", name, "-o", name[:-2] + ".o"], tmp,
                                            "the FMU runtime"), c_files))
        _run([cc, "-r", *[n[:-2] + ".o" for n in c_files], "-o", filename], tmp, "the FMU runtime")
        return tmp / filename

    return cached_build(key, f"lcg_fmu_fmi{fmi_version}_{key}", filename, make, lambda name, path: path)[1]


def _check_identifier(identifier: str) -> None:
    taken = {Path(f).stem for f in (*CORE_FILES, *FMI_FILES[2], *FMI_FILES[3], MODEL_TABLE,
                                    *FMI_HEADERS[2], *FMI_HEADERS[3])}
    if identifier in taken:
        raise ModelError(f"export_fmu: the model identifier {identifier!r} is the name of one of the FMU's own "
                         f"files ({', '.join(sorted(taken))}): give the model another name, or model_identifier=...")


def _check_version(fmi_version) -> None:
    if fmi_version not in FMI_VERSIONS:
        raise ModelError(f"export_fmu: fmi_version must be 2 or 3, got {excerpt(fmi_version)}")


def _assemble(code, table: VariableTable, *, fmi_version: int, x_start: Sequence[float], p_start: Sequence[float],
              header: dict, constrained: bool) -> tuple[dict[str, str], str]:
    """The FMU's files (the generated ``code``, the runtime, the model table) and its
    modelDescription.xml."""
    _check_names(table)
    identifier = code.prefix
    files: dict[str, str] = {name: text for name, text in code.files.items()}
    files.update(runtime_files(fmi_version))
    c_files = sorted(n for n in files if n.endswith(".c")) + [MODEL_TABLE]
    # The token digests everything but itself: the model's code, the glue, the variables.
    token = _token([f"fmi {fmi_version}", *(f"{k}\0{v}" for k, v in sorted(files.items())),
                    repr(table.variables), repr(sorted(header.items())),
                    *([repr([v.unit for v in table.variables])] if any(v.unit for v in table.variables) else [])])
    params = [v.name for v in table.of_kind("parameter", "input")]
    ctx = dict(version=__version__, identifier=identifier, model_name=header["model_name"], token=token,
               prefix=code.prefix, nx=table.nx, np=table.np, nout=table.nout,
               state_names=[v.name for v in table.of_kind("state")], param_names=params,
               input_names=[v.name for v in table.of_kind("input")],
               output_names=[v.name for v in table.of_kind("output")], x_start=[repr(float(v)) for v in x_start],
               p_start=[repr(float(v)) for v in p_start], tolerance=repr(float(header["tolerance"])),
               constrained=constrained)
    files[MODEL_TABLE] = environment().get_template("fmu/lcg_fmu_model.c.j2").render(**ctx)
    h = Header(identifier=identifier, token=token, **header)
    if fmi_version == 2:
        description = model_description_fmi2(table, h, c_files)
    else:
        description = model_description_fmi3(table, h)
        files["buildDescription.xml"] = build_description_fmi3(identifier, c_files)
    return files, description


def fmu_sources(scene: Scene, *, fmi_version: int, x_start: Sequence[float], tunable: set[str], header: dict
                ) -> tuple[dict[str, str], str, VariableTable]:
    """The FMU's C sources (file name -> text, flat: the folder ``sources/`` of the archive, the
    standard's headers included), its modelDescription.xml and its variables. ``header``: the
    fields of :class:`~.description.Header` but the identifier and the token."""
    _check_version(fmi_version)
    _check_identifier(scene.prefix)
    code = generate_code(scene, "c")
    table = variable_table(scene, x_start=list(x_start), tunable=tunable)
    files, description = _assemble(code, table, fmi_version=fmi_version, x_start=x_start,
                                   p_start=code.param_defaults, header=header, constrained=False)
    return files, description, table


#: The Baumgarte rates of a constrained FMU: fixed parameters after the model's own.
BAUMGARTE_PARAMETERS = ("baumgarte_alpha", "baumgarte_beta")


def constrained_fmu_sources(system: ConstrainedSystem, *, fmi_version: int, x_start: Sequence[float],
                            tunable: set[str], outputs: Sequence[str], values: Mapping[str, float],
                            baumgarte, prefix: str | None, header: dict
                            ) -> tuple[dict[str, str], str, VariableTable]:
    """:func:`fmu_sources` of a constrained system in its index-1 form (eq. 4.5 with Baumgarte
    stabilization f'' + 2 alpha f' + beta^2 f = 0): the FMU's states are (q, q'); alpha and beta
    are the fixed parameters ``baumgarte_alpha``, ``baumgarte_beta`` (negative: the natural rate
    of the system at the initial state, as ``baumgarte="auto"`` in simulate()); the outputs'
    dependencies are not listed (every state and parameter)."""
    _check_version(fmi_version)
    code, info = generate_constrained(system, ggl=False, outputs=list(outputs), events=(), runtime_parameters=None,
                                      values=dict(values), prefix=prefix, lang="c")
    _check_identifier(code.prefix)
    for name in BAUMGARTE_PARAMETERS:
        if name in code.param_names:
            raise ModelError(f"export_fmu: the parameter name {name!r} is the FMU's Baumgarte rate: rename it")
    alpha, beta = (-1.0, -1.0) if baumgarte == BAUMGARTE_AUTO else baumgarte
    nx = 2 * info.n
    params = [(name, value, "parameter", "tunable" if name in tunable else "fixed", "")
              for name, value in zip(code.param_names, code.param_defaults)]
    params += [(BAUMGARTE_PARAMETERS[0], alpha, "parameter", "fixed",
                "Baumgarte rate alpha (negative: the natural rate at the initial state)"),
               (BAUMGARTE_PARAMETERS[1], beta, "parameter", "fixed",
                "Baumgarte rate beta (negative: the natural rate at the initial state)")]
    table = build_table(code.state_names, list(x_start), [None] * nx, params,
                        [(name, None) for name in info.output_names])
    files, description = _assemble(code, table, fmi_version=fmi_version, x_start=x_start,
                                   p_start=[p[1] for p in params], header=header, constrained=True)
    return files, description, table


def export_fmu(source: Model | ModelFile | str | os.PathLike, path: str | os.PathLike, *, fmi_version: int = 2,
               outputs: Sequence[str] | None = None, tunable: Sequence[str] | None = None,
               values: Mapping[str, float] | None = None, initial: Mapping[str, float] | None = None,
               model_identifier: str | None = None, tolerance: float | None = None,
               start_time: float | None = None, stop_time: float | None = None, baumgarte=None) -> Path:
    """Write ``source`` (a :class:`Model`, a :class:`ConstrainedSystem`, a loaded :class:`ModelFile`
    or a model file's path) as an FMU at ``path``: Model Exchange and Co-Simulation in one archive,
    FMI 2.0 or 3.0.

    The FMU's states are y = (q, q') named as in ``simulate()``'s CSV (``theta``, ``theta_dot``),
    their derivatives ``der(theta)``; every parameter of the model is a parameter of the FMU
    (``tunable`` ones may change during a simulation, the others are fixed after initialization);
    the model's inputs (:meth:`Model.input`) are FMI inputs (held between communication points in
    Co-Simulation, the importer's values in Model Exchange); ``outputs`` are scene outputs
    (:class:`Scene`). Co-Simulation integrates inside the FMU with Dormand-Prince 5(4) and a PI
    step size controller (lcg_dopri.c) to the importer's relative tolerance (absolute: 1e-3 of
    it), or ``tolerance`` when the importer gives none. The binary is compiled for this machine
    (``binaries/linux64`` for FMI 2.0, ``binaries/x86_64-linux`` for FMI 3.0 on x86-64 Linux);
    ``sources/`` holds every C file (FMI 2.0: the ``SourceFiles`` lists; FMI 3.0:
    ``sources/buildDescription.xml``) so that it builds elsewhere.

    A constrained system is exported in its index-1 form (eq. 4.5 with Baumgarte stabilization,
    :func:`constrained_fmu_sources`): states (q, q'), outputs as a constrained run's (default:
    energy, the multipliers ``lambda_<j>``, the residuals ``g_<j>``, ``gdot_<j>``), the Baumgarte
    rates as the fixed parameters ``baumgarte_alpha``, ``baumgarte_beta``. Projection onto the
    constraints (a step of the integrator) is not part of an FMU; events and inequality
    constraints (no event indicators) are refused.

    Parameters
    ----------
    source:
        The model. A model file's settings are the defaults: ``[simulation]`` outputs,
        runtime_parameters (the tunable ones), parameters (start values), initial (start values
        of the states), t_start, t_end and rtol (the DefaultExperiment).
    fmi_version:
        2 or 3.
    outputs:
        Output names (default: the file's outputs, else energy and the positions of the points).
    tunable:
        Parameters the importer may change during a simulation (default: the file's
        runtime_parameters, else all).
    values, initial:
        Start values of parameters (and inputs) and of states by name (missing states: 0).
    model_identifier:
        The C name of the FMU's binary (default: the model's name).
    tolerance, start_time, stop_time:
        The DefaultExperiment (tolerance also the Co-Simulation default).
    baumgarte:
        Constrained systems: ``"auto"`` (alpha = beta = the natural rate of the system at the
        initial state, computed when initialization ends, as simulate() does at each run's start)
        or (alpha, beta); default: the file's index-1 setting, else "auto".
    """
    problem = fmu_path_problem(path)
    if problem:
        raise LagcodegenError(f"export_fmu: {problem}")
    mf = _model_file(source)
    system = None
    if mf is not None:
        model, s, system = mf.model, mf.simulation, mf.constrained
        eom = mf.derive() if system is None else None
    elif isinstance(source, ConstrainedSystem):
        model, s, system, eom = source.model, None, source, None
    elif isinstance(source, Model):
        model, s = source, None
        eom = derive(model)
    else:
        raise ModelError(f"export_fmu: source must be a Model, a ConstrainedSystem, a ModelFile or a model file's "
                         f"path, got {type(source).__name__}")
    if system is not None:
        if (mf is not None and mf.events) or system.inequalities:
            raise ModelError("export_fmu: events and inequality constraints need event indicators, which lagcodegen's "
                             "FMUs do not have: export the system without them")
        if baumgarte is None:
            baumgarte = s.baumgarte if s is not None and s.formulation in (None, "index1") else BAUMGARTE_AUTO
        baumgarte = check_baumgarte(baumgarte, "export_fmu: baumgarte")
        if outputs is None:
            outputs = constrained_outputs(system, s.outputs if s is not None else [], "index1")
    elif outputs is None:
        outputs = list(s.outputs) if s is not None and s.outputs else (["energy", "positions"] if model.points
                                                                        else ["energy"])
    names = [p.name for p in model.params]
    if tunable is None:
        tunable = s.runtime_parameters if s is not None and s.runtime_parameters is not None else names
    for name in tunable:
        if name not in names:
            raise ModelError(f"export_fmu: tunable parameter {name!r} is not a parameter of the model "
                             f"(parameters: {', '.join(names) or 'none'})")
    vals = dict(s.parameters) if s is not None else {}
    vals.update(values or {})
    init = dict(s.initial) if s is not None else {}
    for name, value in (initial or {}).items():
        init[name] = check_finite(value, f"export_fmu: initial value of {name!r}")
    state_names = [q.name for q in model.coords] + [v.name for v in model.v]  # (q, v): nq + nv states
    neutral = dict(zip([q.name for q in model.coords], model.neutral()))  # quaternions at the identity
    for name in init:
        if name not in state_names:
            raise ModelError(f"export_fmu: initial value given for {name!r}, which is not a coordinate or velocity "
                             f"(state: {', '.join(state_names)})")
    x_start = ([float(init.get(name, neutral.get(name, 0.0))) for name in state_names]
               + [0.0] * (len(eom.quadratures) if eom else 0))
    if tolerance is None:
        tolerance = s.rtol if s is not None and s.rtol > 0 else DEFAULT_TOLERANCE
    tolerance = check_finite(tolerance, "export_fmu: tolerance")
    if not tolerance > 0:
        raise ModelError(f"export_fmu: tolerance must be positive, got {tolerance:g}")
    t0 = start_time if start_time is not None else (s.t_start if s is not None else 0.0)
    t1 = stop_time if stop_time is not None else (s.t_end if s is not None else None)
    header = dict(model_name=model.name, description=f"lagcodegen model {model.name}", start_time=float(t0),
                  stop_time=None if t1 is None else float(t1), tolerance=float(tolerance))
    if system is None:
        scene = Scene(eom, jacobian=False, outputs=outputs, runtime_parameters=None, values=vals,
                      prefix=model_identifier)
        files, description, _ = fmu_sources(scene, fmi_version=fmi_version, x_start=x_start, tunable=set(tunable),
                                            header=header)
    else:
        header["description"] = f"lagcodegen model {model.name}, constrained, index-1 form with Baumgarte stabilization"
        files, description, _ = constrained_fmu_sources(system, fmi_version=fmi_version, x_start=x_start,
                                                        tunable=set(tunable), outputs=outputs, values=vals,
                                                        baumgarte=baumgarte, prefix=model_identifier, header=header)
    plat, suffix = _binary_folder(fmi_version)
    identifier = model_identifier or model.name  # the scene's prefix
    cc = os.environ.get("CC") or "cc"  # the compiler of the build: $CC, as for model libraries
    path = Path(path)
    with tempfile.TemporaryDirectory(prefix="lcg_fmu_") as tmp:
        work = Path(tmp)
        for name, text in files.items():
            (work / name).write_text(text)
        library = f"{identifier}{suffix}"
        runtime = set(runtime_files(fmi_version))
        model_c = sorted(n for n in files if n.endswith(".c") and n not in runtime)
        _run([cc, *FMU_CFLAGS, "-shared", *model_c, str(runtime_object(fmi_version, cc)), "-o", library, "-lm"], work,
             "the FMU's sources")
        staged = work / "out.fmu"
        with zipfile.ZipFile(staged, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("modelDescription.xml", description)
            zf.write(work / library, f"binaries/{plat}/{library}")
            for name in sorted(files):
                zf.writestr(f"sources/{name}", files[name])
            zf.writestr("documentation/licenses/fmi-standard-headers.txt", (INCLUDE_DIR / "LICENSE.txt").read_text())
        path.parent.mkdir(parents=True, exist_ok=True)
        shutil.move(str(staged), str(path))
    return path
