"""The catalogue of output names a simulation may ask for (one place for the scene, the
constrained formulations and the model files)."""

#: Output groups of every model besides single outputs (p_<q>, <point>_x, user outputs).
OUTPUT_GROUPS = ("energy", "kinetic_energy", "potential_energy", "momenta", "positions", "dissipation",
                 "jacobi_h", "dh_dt")
#: Output groups of constrained systems, besides the model's.
CONSTRAINT_OUTPUT_GROUPS = ("lambda", "constraint_forces", "residuals", "inequalities")
#: Outputs of a constrained simulation when none are named.
DEFAULT_CONSTRAINED_OUTPUTS = ("energy", "lambda", "residuals")
