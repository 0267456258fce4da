"""The time loop: composes fluid, phase field, particles and outputs.

``SOLVERS`` maps each implemented ``constitutive_eq.type`` to a function
``run(cfg, args) -> exit code``; a solver module registers itself with ``register``.
"""
from __future__ import annotations

SOLVERS: dict = {}


def register(type_name: str):
    """Decorator: make ``fn(cfg, args) -> int`` the runner of ``constitutive_eq.type``."""
    def deco(fn):
        SOLVERS[type_name] = fn
        return fn
    return deco
