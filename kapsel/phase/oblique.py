"""The Cahn-Hilliard step in the oblique (Lees-Edwards) frame (eq 32): the metric operators
of kapsel.fluid.oblique in the solver of kapsel.phase.cahn_hilliard (Shear_NS_LE_CH_FDM)."""
from __future__ import annotations

import numpy as np

from ..mesh.oblique import contravariant, oblique_gradient, oblique_laplacian
from ..mesh.halo import WholeFields
from .cahn_hilliard import CahnHilliard

__all__ = ["ObliqueCahnHilliard", "make_oblique_cahn_hilliard"]


class ObliqueCahnHilliard:
    """Mixin of the Cahn-Hilliard solver in the oblique frame (eq 32):
    d_t psi + d^_i (xi^i psi) = kappa G^ij d^_i d^_j mu, xi^i the contravariant deviation
    velocity, mu with the metric Laplacian and the physical |grad phi|^2; the capillary force
    uses the physical gradient (Cartesian components, converted by the MAC solver).
    ``frame()`` returns the current frame strain g.  The operators run on the block widened
    by the solver's halo (identities on one process); the implicit operator through them
    (no width-2 shortcut: ``halo2`` None)."""

    halo = WholeFields()      # used alone, on whole fields; a solver sets its own

    def _lap(self, f, out):
        h = self.halo
        lead = f.shape[:-3]
        L = oblique_laplacian(h.pad(f, key="ch"), self.dx, self.frame(),
                              h.target(out, lead, "chlap"), work=h.work(lead, "chlapw"))
        return h.keep(L, out)

    def _grad(self, f, out):
        h = self.halo
        G = oblique_gradient(h.pad(f, key="ch"), self.dx, self.frame(),
                             h.target(out, (3,), "chgrad"))
        return h.keep(G, out)

    def _grad_sq(self, f):
        gr = self._grad(f, np.empty((3,) + f.shape))
        return np.einsum("i...,i...->...", gr, gr)

    def _div_coef_grad(self, c, f):
        """div(c grad f) = c lap f + grad c . grad f with the metric Laplacian and the
        physical central gradient: the original's form of the z term, -(alpha + 2 z phi)
        lap psi - 2 z grad phi . grad psi (PHYSICS-EXTRA.md §2.5), in the oblique frame."""
        out = c * self._lap(f, np.empty(f.shape))
        gc = self._grad(c, np.empty((3,) + f.shape))
        gf = self._grad(f, np.empty((3,) + f.shape))
        out += np.einsum("i...,i...->...", gc, gf)
        return out

    def _z_density(self, s, psi):
        """z phi_s |grad psi|^2 with the physical gradient (the free energy record)."""
        return self.z * s * self._grad_sq(psi)

    def _div_flux(self, psi, u, out, work):
        return CahnHilliard._div_flux(self, psi, contravariant(u, self.frame()), out, work)


class _ObliqueCH(ObliqueCahnHilliard, CahnHilliard):
    """The Cahn-Hilliard solver with the oblique operators (``make_oblique_cahn_hilliard``)."""


def make_oblique_cahn_hilliard(frame, max_strain, *args, **kwargs):
    """A CahnHilliard (kapsel.phase.cahn_hilliard; its arguments, ``layout`` too) with the
    oblique operators, ``frame()`` the frame strain g; its |k|^2 (the stability estimate and
    the implicit scheme's Fourier symbol) bounds the metric Laplacian of the largest strain
    |g| <= ``max_strain``: |k|^2 (1 + (4 g^2 + 2 g) / 12)."""
    ch = _ObliqueCH(*args, **kwargs)
    ch.halo2 = None
    ch.frame = frame
    g = max_strain
    ch._k2 = ch._k2 * (1.0 + (4 * g * g + 2 * g) / 12.0)
    return ch
