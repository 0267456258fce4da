"""The fluid in the walls' solid held exactly at rest: the projection onto divergence-free
fields that vanish on the solid (FLAT walls, kapsel.particles.walls; PHYSICS-EXTRA.md §2.3).

Why it is needed.  The SPM step adds the rigidity increment of the particles and of the walls
in one combined field du (= sum_i phi_i (V_i + Omega_i x r) - phi u*, the walls at rest, as
the original does) and makes it divergence-free: u = P(u* + du), with P the solver's
projection (spectral I - k k / k^2, or the B-grid MAC projection).  u* + du vanishes in the
solid, but P subtracts the gradient of the pressure that removes the divergence of du, and
that pressure is global: where particles move, grad q reaches into the solid.  The original
(and kapsel-py up to this module) therefore leaves a velocity of several per cent of max|u|
in the solid (measured with ex14's walls and two settling particles: 7 % of max|u| after
5 steps, a net solid momentum of 2-5 % of the largest sum|u|); ordering the wall and the
particle increments differently does not help, the leak comes from the projection itself,
and repeating impose + project converges slowly (3 passes: 1.5 %).

What is done.  With S the solid nodes (phi_wall = 1) and R the restriction to them, the
fluid velocity after the step is the orthogonal projection of w = u* + du onto the fields
that are divergence-free AND vanish on S:

    u = P(w - R^T lam),   lam (3 components on S) solving   M lam = R P w,   M = R P R^T.

(u is in both subspaces by construction, and w - u = (I - P) w + (I - P) R^T lam ... is
orthogonal to every field of their intersection, so this is the exact projection onto it.)
The body force -R^T lam acts only inside the solid: it is the force by which the walls hold
their fluid at rest against the pressure of the particles.  P is translation invariant along
the walls, so M is block diagonal in the Fourier modes (k1, k2) along the wall: one small
(3 Ns x 3 Ns) Hermitian block per mode, Ns = number of solid planes.  The blocks are measured
once by applying the solver's own projection to unit impulses on the solid planes (3 Ns
projections), so they are exact for whichever P the solver uses; they are inverted by the
pseudo-inverse (at k1 = k2 = 0 the normal component is singular: P keeps only the mean of
u_normal, so the condition is that no net flux crosses the walls, which the minimum-norm
lam gives); one step of iterative refinement on the small systems follows.  A step then
costs one more projection (and, spectral, one inverse FFT to read u on the planes).

Accuracy: with the B-grid MAC projection the velocity on S is zero to round-off for any
solid thickness (|u_S| / max|u| <= 1e-15 for white-noise fields, DH = 4 .. 16).  The
spectral projection is global: the spectral gradient of a smooth bump deep inside a thick
solid is nearly confined to the solid, so M becomes ill-conditioned as the solid thickens,
lam grows and the round-off eps |lam| of applying P to it remains.  White-noise fields
(the worst case), 64^3: |u_S| / max|u| = 3e-15 (DH = 4, 3 solid planes), 1e-13 (DH = 6),
2e-12 (DH = 8), 1e-10 (DH = 10), 2e-8 (DH = 16); ex14's walls (DH = 4) with settling
particles: 1e-15.  Eigenvalues of M below RCOND (relative) are treated as null.

Memory: (3 Ns)^2 N1 (N2/2 + 1) complex numbers (ex14 at 64^3, Ns = 3: 9 MB).
"""
from __future__ import annotations

import numpy as np

__all__ = ["SolidRest"]


class SolidRest:
    """Exact rest of the fluid on the solid planes of ``wall`` (kapsel.particles.walls.
    FlatWall) for a solver projection ``project(f) -> P f`` of real fields (3, NX, NY, NZ)
    (may work in place on f)."""

    RCOND = 1e-13
    REFINE = 1

    def __init__(self, wall, project):
        self.axis = wall.axis
        self.shape = tuple(wall.shape)
        self.planes = np.flatnonzero(wall.profile >= 1.0 - 1e-12)
        ns = len(self.planes)
        self.ns = ns
        if not ns:
            self.minv = None
            return
        inplane = [n for a, n in enumerate(self.shape) if a != self.axis]
        self.n1, self.n2 = inplane
        m = 3 * ns
        M = np.empty((self.n1, self.n2 // 2 + 1, m, m), dtype=complex)
        f = np.zeros((3,) + self.shape)
        for a in range(3):
            for j, s in enumerate(self.planes):
                f[...] = 0.0
                idx = [a, 0, 0, 0]
                idx[1 + self.axis] = s
                f[tuple(idx)] = 1.0
                M[..., a * ns + j] = self._planes_hat(project(f))
        M = 0.5 * (M + np.conj(np.swapaxes(M, -1, -2)))       # Hermitian up to round-off
        self.M = M
        self.minv = np.linalg.pinv(M, rcond=self.RCOND, hermitian=True)

    def _planes_hat(self, u):
        """Fourier transform along the walls of u on the solid planes, (n1, n2h, 3 ns),
        component-major (index a ns + j for component a on plane j)."""
        v = np.ascontiguousarray(np.moveaxis(np.take(u, self.planes, axis=1 + self.axis),
                                             1 + self.axis, 1))       # (3, ns, n1, n2)
        h = np.fft.rfft2(v).reshape(3 * self.ns, self.n1, -1)
        return np.ascontiguousarray(h.transpose(1, 2, 0))

    def force(self, u, out):
        """Write -R^T lam into ``out`` (3, NX, NY, NZ), zero off the solid planes, for the
        divergence-free u = P w of the step (module docstring): u + P(out) vanishes on the
        solid.  ``out`` is fully overwritten on the planes only: keep it zero elsewhere."""
        if self.minv is None:
            return out
        r = self._planes_hat(u)[..., None]                    # (n1, n2h, 3 ns, 1)
        lam = self.minv @ r
        for _ in range(self.REFINE):          # iterative refinement of the small solves
            lam += self.minv @ (r - self.M @ lam)
        lam = lam[..., 0].transpose(2, 0, 1).reshape(3, self.ns, self.n1, -1)
        lam = np.fft.irfft2(lam, s=(self.n1, self.n2))        # (3, ns, n1, n2)
        for j, s in enumerate(self.planes):
            idx = [slice(None)] * 4
            idx[1 + self.axis] = s
            out[tuple(idx)] = -lam[:, j]
        return out
