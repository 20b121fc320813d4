"""modelDescription.xml (FMI 2.0 and 3.0) and sources/buildDescription.xml (FMI 3.0) of an FMU:
one job, the XML text from a :class:`~.variables.VariableTable`.

Both versions declare Model Exchange and Co-Simulation for one model identifier, the variables
(time independent; states local with ``initial="exact"`` start values; their derivatives
``der(<state>)`` calculated; run-time parameters tunable or fixed; inputs continuous; outputs
calculated) and the ModelStructure with the dependencies of the derivatives and outputs.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from xml.sax.saxutils import quoteattr

from ..version import __version__
from .variables import Variable, VariableTable


@dataclass(frozen=True)
class Header:
    """What the root element and the experiment say."""

    model_name: str
    identifier: str
    token: str
    description: str
    start_time: float
    stop_time: float | None
    tolerance: float


#: A variable name of FMI's "structured" naming convention as lagcodegen writes them: an ASCII
#: identifier, or ``der(`` one ``)``. Any other name (``θ``, ``der(θ)``: the standards' grammar has
#: no non-ASCII characters, not even in q-names) makes the FMU's convention "flat" (any Unicode).
_STRUCTURED = re.compile(r"[A-Za-z_][A-Za-z0-9_]*|der\([A-Za-z_][A-Za-z0-9_]*\)")


def naming_convention(table: VariableTable) -> str:
    """``"structured"`` if every variable name of ``table`` is one of that convention, else ``"flat"``
    (the names stay those of ``simulate()``'s CSV either way)."""
    return "structured" if all(_STRUCTURED.fullmatch(v.name) for v in table.variables) else "flat"


def _num(value: float) -> str:
    return repr(float(value))


def _attrs(**attrs) -> str:
    return "".join(f" {k}={quoteattr(str(v))}" for k, v in attrs.items() if v is not None)


def _deps(refs, index=None) -> str | None:
    """The dependencies attribute (value references, or FMI 2.0 indices through ``index``); None
    (no attribute: every state and input) when the dependencies are not known."""
    if refs is None:
        return None
    return " ".join(str(index[r] if index else r) for r in refs)


def _unit_definitions(table: VariableTable) -> str:
    """The UnitDefinitions element declaring every unit the variables state ("" when none do)."""
    units = sorted({v.unit for v in table.variables if v.unit})
    if not units:
        return ""
    return "  <UnitDefinitions>\n" + "".join(f"    <Unit{_attrs(name=u)}/>\n" for u in units) + "  </UnitDefinitions>\n"


def _experiment(h: Header) -> str:
    stop = None if h.stop_time is None else _num(h.stop_time)
    return f"  <DefaultExperiment{_attrs(startTime=_num(h.start_time), stopTime=stop, tolerance=_num(h.tolerance))}/>\n"


def _fmi2_variable(v: Variable) -> str:
    desc = v.description or None
    if v.kind == "time":
        head = _attrs(name=v.name, valueReference=v.vr, description=desc, causality="independent",
                      variability="continuous")
        real = "<Real/>"
    elif v.kind == "state":
        head = _attrs(name=v.name, valueReference=v.vr, description=desc, causality="local",
                      variability="continuous", initial="exact")
        real = f"<Real{_attrs(start=_num(v.start))}/>"
    elif v.kind == "derivative":
        head = _attrs(name=v.name, valueReference=v.vr, description=desc, causality="local",
                      variability="continuous", initial="calculated")
        real = f"<Real{_attrs(derivative=v.derivative_of + 1)}/>"  # 1-based index of the state
    elif v.kind == "parameter":
        head = _attrs(name=v.name, valueReference=v.vr, description=desc, causality="parameter",
                      variability=v.variability, initial="exact")
        real = f"<Real{_attrs(start=_num(v.start))}/>"
    elif v.kind == "input":
        head = _attrs(name=v.name, valueReference=v.vr, description=desc, causality="input", variability="continuous")
        real = f"<Real{_attrs(start=_num(v.start))}/>"
    else:
        head = _attrs(name=v.name, valueReference=v.vr, description=desc, causality="output",
                      variability="continuous", initial="calculated")
        real = "<Real/>"
    if v.unit:
        real = real.replace("<Real", f"<Real{_attrs(unit=v.unit)}", 1)
    return f"    <ScalarVariable{head}>\n      {real}\n    </ScalarVariable>\n"


def model_description_fmi2(table: VariableTable, h: Header, source_files: list[str]) -> str:
    """modelDescription.xml of an FMI 2.0 FMU (ScalarVariable i has value reference i - 1)."""
    files = "".join(f"      <File{_attrs(name=f)}/>\n" for f in source_files)
    common = _attrs(modelIdentifier=h.identifier, canNotUseMemoryManagementFunctions="true",
                    canGetAndSetFMUstate="false", canSerializeFMUstate="false",
                    providesDirectionalDerivative="false")
    root = _attrs(fmiVersion="2.0", modelName=h.model_name, guid=h.token, description=h.description,
                  generationTool=f"lagcodegen {__version__}", variableNamingConvention=naming_convention(table),
                  numberOfEventIndicators=0)
    cs = _attrs(canHandleVariableCommunicationStepSize="true", canInterpolateInputs="false",
                maxOutputDerivativeOrder=0)
    out = ['<?xml version="1.0" encoding="UTF-8"?>\n',
           f"<fmiModelDescription{root}>\n",
           f"  <ModelExchange{common}>\n    <SourceFiles>\n{files}    </SourceFiles>\n  </ModelExchange>\n",
           f"  <CoSimulation{common}{cs}>\n    <SourceFiles>\n{files}    </SourceFiles>\n  </CoSimulation>\n",
           _unit_definitions(table),
           '  <LogCategories>\n    <Category name="logStatusError"/>\n  </LogCategories>\n',
           _experiment(h),
           "  <ModelVariables>\n"]
    out += [_fmi2_variable(v) for v in table.variables]
    out.append("  </ModelVariables>\n  <ModelStructure>\n")
    index = {v.vr: v.vr + 1 for v in table.variables}
    outputs = table.of_kind("output")
    if outputs:
        out.append("    <Outputs>\n")
        out += [f"      <Unknown{_attrs(index=index[v.vr], dependencies=_deps(v.dependencies, index))}/>\n"
                for v in outputs]
        out.append("    </Outputs>\n")
    derivatives = table.of_kind("derivative")
    if derivatives:
        out.append("    <Derivatives>\n")
        out += [f"      <Unknown{_attrs(index=index[v.vr], dependencies=_deps(v.dependencies, index))}/>\n"
                for v in derivatives]
        out.append("    </Derivatives>\n")
    unknowns = sorted(table.of_kind("derivative", "output"), key=lambda v: v.vr)
    if unknowns:
        out.append("    <InitialUnknowns>\n")
        out += [f"      <Unknown{_attrs(index=index[v.vr])}/>\n" for v in unknowns]
        out.append("    </InitialUnknowns>\n")
    out.append("  </ModelStructure>\n</fmiModelDescription>\n")
    return "".join(out)


def _fmi3_variable(v: Variable) -> str:
    desc = v.description or None
    if v.kind == "time":
        attrs = _attrs(name=v.name, valueReference=v.vr, description=desc, causality="independent",
                       variability="continuous")
    elif v.kind == "state":
        attrs = _attrs(name=v.name, valueReference=v.vr, description=desc, causality="local",
                       variability="continuous", initial="exact", start=_num(v.start))
    elif v.kind == "derivative":
        attrs = _attrs(name=v.name, valueReference=v.vr, description=desc, causality="local",
                       variability="continuous", initial="calculated", derivative=v.derivative_of)
    elif v.kind == "parameter":
        attrs = _attrs(name=v.name, valueReference=v.vr, description=desc, causality="parameter",
                       variability=v.variability, initial="exact", start=_num(v.start))
    elif v.kind == "input":
        attrs = _attrs(name=v.name, valueReference=v.vr, description=desc, causality="input",
                       variability="continuous", start=_num(v.start))
    else:
        attrs = _attrs(name=v.name, valueReference=v.vr, description=desc, causality="output",
                       variability="continuous", initial="calculated")
    if v.unit:
        attrs += _attrs(unit=v.unit)
    return f"    <Float64{attrs}/>\n"


def model_description_fmi3(table: VariableTable, h: Header) -> str:
    """modelDescription.xml of an FMI 3.0 FMU."""
    common = _attrs(modelIdentifier=h.identifier, canGetAndSetFMUState="false", canSerializeFMUState="false",
                    providesDirectionalDerivatives="false", providesAdjointDerivatives="false")
    root = _attrs(fmiVersion="3.0", modelName=h.model_name, instantiationToken=h.token, description=h.description,
                  generationTool=f"lagcodegen {__version__}", variableNamingConvention=naming_convention(table))
    cs = _attrs(canHandleVariableCommunicationStepSize="true", maxOutputDerivativeOrder=0, hasEventMode="false",
                providesIntermediateUpdate="false")
    out = ['<?xml version="1.0" encoding="UTF-8"?>\n',
           f"<fmiModelDescription{root}>\n",
           f"  <ModelExchange{common}/>\n",
           f"  <CoSimulation{common}{cs}/>\n",
           _unit_definitions(table),
           '  <LogCategories>\n    <Category name="logStatusError"/>\n  </LogCategories>\n',
           _experiment(h),
           "  <ModelVariables>\n"]
    out += [_fmi3_variable(v) for v in table.variables]
    out.append("  </ModelVariables>\n  <ModelStructure>\n")
    out += [f"    <Output{_attrs(valueReference=v.vr, dependencies=_deps(v.dependencies))}/>\n"
            for v in table.of_kind("output")]
    out += [f"    <ContinuousStateDerivative{_attrs(valueReference=v.vr, dependencies=_deps(v.dependencies))}/>\n"
            for v in table.of_kind("derivative")]
    out += [f"    <InitialUnknown{_attrs(valueReference=v.vr)}/>\n"
            for v in sorted(table.of_kind("derivative", "output"), key=lambda v: v.vr)]
    out.append("  </ModelStructure>\n</fmiModelDescription>\n")
    return "".join(out)


def build_description_fmi3(identifier: str, source_files: list[str]) -> str:
    """sources/buildDescription.xml of an FMI 3.0 FMU: one C99 source file set, linked with libm."""
    files = "".join(f"        <SourceFile{_attrs(name=f)}/>\n" for f in source_files)
    return ('<?xml version="1.0" encoding="UTF-8"?>\n<fmiBuildDescription fmiVersion="3.0">\n'
            f"  <BuildConfiguration{_attrs(modelIdentifier=identifier)}>\n"
            '    <SourceFileSet language="C99">\n'
            f"{files}    </SourceFileSet>\n"
            '    <Library name="m"/>\n'
            "  </BuildConfiguration>\n</fmiBuildDescription>\n")
