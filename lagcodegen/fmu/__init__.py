"""FMU export: a model as a Functional Mock-up Unit (FMI 2.0 or 3.0, Model Exchange and
Co-Simulation in one archive) that other simulation tools import; constrained systems in their
index-1 form with Baumgarte stabilization.

The package, one job a module: :mod:`.variables` (the FMU's variables, value references and
dependencies from a scene), :mod:`.description` (modelDescription.xml, buildDescription.xml) and
:mod:`.export` (:func:`export_fmu`: sources, compiled binary, the zip). The C that runs inside
every FMU is model-independent (``templates/fmu``: the core ``lcg_fmu_core.c``, the FMI functions
``lcg_fmi2.c``/``lcg_fmi3.c``, the Dormand-Prince integrator ``lcg_dopri.c``); ``include/`` holds
the FMI standard's headers (modelica/fmi-standard, tags v2.0.5 and v3.0.2), unchanged, under their
BSD 2-clause licence (``include/LICENSE.txt``; every FMU carries it in
``documentation/licenses/``).
"""

from .export import FMI_VERSIONS, constrained_fmu_sources, export_fmu, fmu_sources  # noqa: F401

__all__ = ["FMI_VERSIONS", "constrained_fmu_sources", "export_fmu", "fmu_sources"]
