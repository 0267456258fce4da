"""kapsel.phase: the binary-fluid order parameter psi (manual §4.2, §5.3)."""
from .cahn_hilliard import CahnHilliard, capillary_force, chemical_potential, discrete_k2, free_energy
from ..errors import SolverDidNotConverge, UnstableTimeStep
from .potentials import FH_EPS, FloryHuggins, Landau, make_potential

__all__ = ["CahnHilliard", "SolverDidNotConverge", "UnstableTimeStep", "capillary_force",
           "chemical_potential", "discrete_k2", "free_energy", "FH_EPS", "FloryHuggins",
           "Landau", "make_potential"]
