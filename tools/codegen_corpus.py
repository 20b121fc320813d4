"""Write every source lagcodegen generates for a fixed set of models into one folder, so that two
trees can be compared byte for byte (``diff -r``): the model code of each example and classic
system in C and Fortran, with and without the Jacobian, folded and run-time parameters, the
tangent/program form, sparse Jacobians, split sources, the Routhian, every constrained
formulation, bundles, the Taylor jet and the model-independent runtimes.

    python tools/codegen_corpus.py OUT_DIR      # then: diff -r OLD_DIR NEW_DIR

Only public entry points are called (they may move; the texts they produce must not change).
"""

from __future__ import annotations

import sys
from pathlib import Path


def main(out: Path) -> int:
    import lagcodegen as lcg
    from lagcodegen.codegen.bundle import render_bundle, render_constrained_bundle
    from lagcodegen.codegen.constrained import generate_constrained
    from lagcodegen.codegen.languages import generate_code
    from lagcodegen.modelfile import load_model
    from lagcodegen.theory.constraints import ConstrainedSystem

    try:
        from lagcodegen.codegen.taylor.emit import jet_sources, runtime_sources as taylor_runtime_sources, \
            taylor_sources
    except ImportError:  # an earlier layout (lagcodegen.solvers.taylor.emit): the texts are the same
        from lagcodegen.solvers.taylor import emit as _e  # type: ignore
        jet_sources, taylor_runtime_sources, taylor_sources = _e.jet_sources, _e.runtime_sources, _e.taylor_sources
    root = Path(__file__).resolve().parents[1]
    count = 0

    def put(group: str, files: dict) -> None:
        nonlocal count
        folder = out / group
        folder.mkdir(parents=True, exist_ok=True)
        for name, text in sorted(files.items()):
            (folder / name).write_text(text)
            count += 1

    def code_files(code) -> dict:
        return dict(code.files)

    S = lcg.systems
    models = {
        "pendulum": S.pendulum(), "double_pendulum": S.double_pendulum(),
        "n_link4": S.n_link_pendulum(4), "n_link18": S.n_link_pendulum(18),
        "oscillator": S.damped_driven_oscillator(), "central": S.central_potential(),
        "spherical": S.spherical_pendulum(), "hoop": S.bead_on_spinning_hoop(),
        "rotating": S.rotating_frame_particle(), "charged": S.charged_particle(),
        "damped_pendulum": S.damped_pendulum(), "spring_chain6": S.spring_chain(6),
    }
    for toml in sorted((root / "examples").glob("*.toml")):
        mf = load_model(toml)
        if mf.constrained is None:
            models[f"file_{toml.stem}"] = mf.model
    for name, model in models.items():
        eom = lcg.derive(model)
        outputs = ["energy", "positions", "momenta", "jacobi_h"]
        for lang in ("c", "fortran"):
            for jac in (True, False):
                scene = lcg.Scene(eom, jacobian=jac, outputs=outputs)
                put(f"ode/{name}/{lang}_jac{int(jac)}", code_files(generate_code(scene, lang)))
            folded = lcg.Scene(eom, jacobian=True, outputs=["energy"], runtime_parameters=[])
            put(f"ode/{name}/{lang}_folded", code_files(generate_code(folded, lang)))
        for form in ("expanded", "tangent"):
            scene = lcg.Scene(eom, jacobian=True, outputs=["energy"], jacobian_form=form)
            put(f"ode/{name}/c_{form}", code_files(generate_code(scene, "c")))
        if model.n <= 6:
            scene = lcg.Scene(eom, jacobian=True, outputs=["energy"], sparse_jacobian=True)
            put(f"ode/{name}/c_sparse", code_files(generate_code(scene, "c")))
        if model.n <= 6:
            scene = lcg.Scene(eom, jacobian=False, outputs=["energy"])
            put(f"taylor/{name}", taylor_sources(scene))
            put(f"taylor_jet/{name}", jet_sources(scene))
        if name in ("pendulum", "double_pendulum", "oscillator"):
            for lang in ("c", "fortran"):
                put(f"bundle/{name}/{lang}", render_bundle(lcg.Scene(eom, jacobian=True, outputs=["energy"]), lang))
    # The Routhian of the central-force problem.
    red = lcg.routh_reduce(S.central_potential())
    scene = lcg.Scene(red.eom, jacobian=True, outputs=["jacobi_h"])
    for lang in ("c", "fortran"):
        put(f"routh/central/{lang}", code_files(generate_code(scene, lang)))
    # Constrained systems: the Cartesian pendulum and the examples' constrained files.
    m = lcg.Model("cartesian_pendulum")
    x, y = m.coordinates("x y")
    l, g, mass = m.parameters(l=1.0, g=9.81, m=1.0)
    m.particle("bob", mass, (x, y))
    m.gravity(g)
    systems = {"cartesian": ConstrainedSystem(m, holonomic=[x**2 + y**2 - l**2])}
    for toml in sorted((root / "examples").glob("*.toml")):
        mf = load_model(toml)
        if mf.constrained is not None:
            systems[f"file_{toml.stem}"] = mf.constrained
    for name, system in systems.items():
        if system.contacts:  # contacts: index 1 only (impact code), no bundle
            for lang in ("c", "fortran"):
                code, _info = generate_constrained(system, ggl=False, lang=lang)
                put(f"constrained/{name}/{lang}_ggl0", code_files(code))
            continue
        for lang in ("c", "fortran"):
            for ggl in (False, True):
                code, _info = generate_constrained(system, ggl=ggl, lang=lang)
                put(f"constrained/{name}/{lang}_ggl{int(ggl)}", code_files(code))
        put(f"bundle_constrained/{name}", render_constrained_bundle(system))
    # The model-independent runtimes.
    import importlib
    B = importlib.import_module("lagcodegen.build")
    try:
        put("runtime/cvode", B.runtime_sources(B.find_sundials()))
    except Exception as exc:  # noqa: BLE001 - a corpus of what exists
        print(f"runtime sources not written: {exc}", file=sys.stderr)
    put("runtime/taylor", taylor_runtime_sources())
    print(f"{count} files in {out}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__)
        sys.exit(2)
    sys.exit(main(Path(sys.argv[1])))
