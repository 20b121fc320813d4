"""Formulations: what one simulation needs (:mod:`.scene`) and the language-neutral kernels of
each formulation (:mod:`.kernels` for the ODE of plain, Routhian and minimal-coordinate
models; :mod:`.constrained` for index-1 and GGL)."""
