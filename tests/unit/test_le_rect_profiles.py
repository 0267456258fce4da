"""Lees-Edwards profiles on the rectangular grid (the original's rect-frame coupling:
make_phi.h Relative_coord_check_stepover_Y): every grid point sees the particle at its
Lees-Edwards minimum image."""
import numpy as np
import pytest

from kapsel.frame import lees_edwards_displacement
from kapsel.particles.profile import Stencil, g, lees_edwards_profiles


@pytest.mark.parametrize("offset", [0.0, 0.37, -1.8, 5.25])
def test_rect_profiles_match_the_minimum_image(offset):
    shape, dx, A, xi = (16, 12, 10), 1.0, 2.0, 1.0
    box = np.array(shape, float) * dx
    R = np.array([[3.3, 0.6, 4.2], [12.9, 11.2, 9.7], [7.5, 6.1, 0.4]])
    st = Stencil(A, xi, dx)
    idx, phi, r = lees_edwards_profiles(R, st, shape, dx, offset)
    pts = np.stack(np.meshgrid(*[np.arange(n) * dx for n in shape], indexing="ij"), -1)
    pts = pts.reshape(-1, 3)
    for n in range(len(R)):
        dense = np.zeros(pts.shape[0])
        np.add.at(dense, idx[n], phi[n])
        d = lees_edwards_displacement(pts - R[n], box, offset)
        want = g(np.sqrt((d * d).sum(-1)), A, xi, dx)
        np.testing.assert_allclose(dense, want, atol=1e-12)
        # r is the displacement of each stencil point from the particle's image
        dr = lees_edwards_displacement(pts[idx[n]] - R[n], box, offset)
        np.testing.assert_allclose(r[n], dr, atol=1e-12)
