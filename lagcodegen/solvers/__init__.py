"""Solver families run on compiled code: native CVODE (:mod:`.cvode`), scikit-sundae
(:mod:`.sksundae`), the constrained formulations on CVODE and IDA (:mod:`.constrained`,
:mod:`.minimal`), switched runs (:mod:`.hybrid`). :mod:`.ode` checks the options of an ODE run
and chooses the family; :mod:`.compiled` is the compiled scene Python sees."""
