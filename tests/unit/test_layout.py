"""The layout of a run on one process (kapsel.mesh.grid.Grid): the sums, gathers, local blocks and
halos of kapsel.parallel are identities on it, its transforms solve on the whole mesh."""
import numpy as np

from kapsel.mesh import operators as op
from kapsel.mesh.grid import Grid
from kapsel.mesh.halo import Halo


def test_one_process_reductions_and_blocks_are_identities():
    g = Grid((4, 6, 8), 0.5)
    assert (g.rank, g.ranks, g.is_root, g.px, g.py) == (0, 1, True, 1, 1)
    assert g.real_range == ((0, 4), (0, 6), (0, 8))
    assert g.spec_range == ((0, 4), (0, 6), (0, 5))
    x = 0.1 + 0.2
    assert g.sum(x) == x and g.max(-x) == -x
    assert g.sums([x, 2.0, -0.0]) == [x, 2.0, -0.0]
    a = np.random.default_rng(0).standard_normal((3,) + g.shape)
    assert g.gather_real(a) is a and g.local_real(a) is a
    c = g.rfft(a)
    assert g.gather_complex(c) is c and g.local_complex(c) is c
    assert np.array_equal(g.k0(c), c[:, 0, 0, 0])
    assert g.dots is None and g.whole_mesh


def test_scalar_solver_inverts_the_laplacian_symbol():
    g = Grid((8, 8, 8), 0.5)
    x, y, z = g.coordinates()
    k = 2 * np.pi / g.box[0]
    f = np.sin(k * x) * np.cos(2 * k * y) + 0.0 * z
    s = g.scalar_solver()
    s.rhs[...] = f
    p = s.solve(s.symbol(op.symbol_inverse_laplacian(g.shape, g.dx, g.spec_range)))
    assert np.allclose(p, -f / (5 * k * k), atol=1e-12)


def test_halo_of_one_process_is_the_block_itself():
    g = Grid((4, 5, 6), 1.0)
    h = Halo(g, 1)
    a = np.random.default_rng(1).standard_normal((3,) + g.shape)
    assert h.trivial and h.pad(a) is a
    out = np.empty_like(a)
    assert h.target(out, (3,)) is out and h.keep(out, out) is out
    assert h.target(None, (3,)).shape == a.shape
    b = a[:, ::-1]                              # not contiguous: a contiguous copy
    assert np.array_equal(h.pad(b), b) and h.pad(b).flags.c_contiguous
