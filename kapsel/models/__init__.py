"""Models: the physics of each constitutive_eq.type.  Importing this package registers every
implemented type in ``kapsel.typespec.SOLVERS``."""
from . import electrolyte, fdm, shear, spectral, zigzag  # noqa: F401
