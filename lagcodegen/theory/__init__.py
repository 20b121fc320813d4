"""The theory of the notes, symbolic only (nothing here compiles): T2/T1/T0 and Jacobi h
(:mod:`.energy`), generalized forces (:mod:`.forces`), ignorable coordinates and the Routhian
(:mod:`.routhian`), steady motion (:mod:`.steady`), linearization (:mod:`.linearize`),
constraints with multipliers (:mod:`.constraints`) and minimal coordinates (:mod:`.minimal`)."""
