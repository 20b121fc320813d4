"""Solver families and run control: one folder per family (:mod:`.cvode`, :mod:`.ida`,
:mod:`.taylor`: its options object, its runner and its ensemble runner), scikit-sundae as a
second backend of CVODE and IDA (:mod:`.sksundae`), the registry that turns a run's options into
a family object (:mod:`.registry`), what the families share (:mod:`.family`, :mod:`.base`) and
run control (:mod:`.control`: Ctrl-C, progress, wall-clock limits; :mod:`.ensemble_run`: one
ensemble call into C; :mod:`.ensemble`: chunks on executors). The compiled models these run are
the faces of :mod:`lagcodegen.simulation`."""
