"""Distributed assembly and solve on PETSc under MPI (:mod:`.solve`): what each rank builds, its connected
components and its part of the interface constraints."""
