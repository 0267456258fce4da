"""Distributed runs over MPI (README "Distributed runs"): imported only by runs started
under mpiexec with more than one rank, or given -X / -Y; a plain run never imports mpi4py."""
