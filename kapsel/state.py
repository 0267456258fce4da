"""A model's state in one place: the fields it carries from one step to the next.

The velocity u (or its transform u_hat), the previous steps the schemes combine (u^{n-1} of
the implicit MAC scheme, eq 25; the advection n^{n-1} of the explicit one's Adams-Bashforth
step; psi^{n-1} of the BDF2 Cahn-Hilliard step, eq 31), the order parameter psi, the ion
densities, the pressure, the capillary force of the last step: each is a named array of
one ``ModelState`` (this rank's block of the mesh in a distributed run).  The solvers
allocate their persistent arrays here and keep a reference (their numerics unchanged); the
model reads and writes them by name (its snapshot sources and its restart,
kapsel.models.common.Model.restart_state / load_restart), so what a continuation needs is
what the state holds.  A previous step is *held* only once a step or a restart gave it
(``holds``): before that the schemes take their first-step forms.

Scratch arrays (used inside one step only) stay with the solvers.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

__all__ = ["ModelState"]


class ModelState:
    """Named step-to-step fields of a model (module docstring)."""

    def __init__(self):
        self._arrays: dict[str, np.ndarray | None] = {}
        self._held: dict[str, bool] = {}

    def field(self, name: str, make: Callable[[], np.ndarray], held: bool = True) -> np.ndarray:
        """The array ``name``, made by ``make()`` (zeros, an FFT-aligned buffer, an initial
        field) the first time it is asked for; ``held``: whether it holds a value from the
        start (False for a previous step, until a step or a restart sets it)."""
        a = self._arrays.get(name)
        if a is None:
            a = make()
            self._arrays[name] = a
            self._held[name] = bool(held)
        return a

    def put(self, name: str, array: np.ndarray | None) -> None:
        """Make ``array`` the field ``name`` (held), or with None drop it (not held)."""
        self._arrays[name] = array
        self._held[name] = array is not None

    def __getitem__(self, name: str) -> np.ndarray:
        return self._arrays[name]

    def get(self, name: str) -> np.ndarray | None:
        """The field ``name`` if it holds a value, else None."""
        return self._arrays.get(name) if self._held.get(name, False) else None

    def __contains__(self, name: str) -> bool:
        return self._arrays.get(name) is not None

    def holds(self, name: str) -> bool:
        """Whether the field ``name`` holds a value (a previous step once a step was made)."""
        return self._held.get(name, False)

    def mark(self, name: str, held: bool = True) -> None:
        """Say that the field ``name`` holds a value now (or no longer)."""
        if name not in self._arrays:
            raise KeyError(name)
        self._held[name] = bool(held)

    def names(self) -> list[str]:
        """The fields, in the order they were made."""
        return [n for n, a in self._arrays.items() if a is not None]

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in self._arrays.values() if a is not None)

    def __repr__(self):
        return "ModelState(" + ", ".join(
            f"{n}{list(self._arrays[n].shape)}{'' if self._held[n] else ' (empty)'}"
            for n in self.names()) + ")"
