"""Run under mpiexec by tests/distributed/test_mpi_layout.py: the distributed layout's pieces of a
Lees-Edwards run (kapsel.mesh.pencil.PencilGrid) against the one-process functions.

    mpiexec -n P python mpi_layout_probe.py PX PY

Checks on every rank (failures raise, which ends every rank):
* ``to_rectangular`` / ``to_oblique`` of a rank's block (scalar and vector fields, linear
  and spline interpolation) are the serial kapsel.fluid.oblique functions of the whole
  field cut to the block, bit for bit;
* ``near_rows`` with Lees-Edwards images holds every particle with a point of its
  rectangular-grid profile stencil (kapsel.particles.profile.lees_edwards_profiles) on the
  block, and only particles whose stencil box meets it;
* the particle table's halos under Lees-Edwards images (kapsel.particles.ownership.Owned
  ``destinations``): every particle whose profile stencil has a point on a rank's block,
  and every pair partner (Lees-Edwards minimum image within the cutoff) of a particle the
  rank owns, goes to that rank;
writes ok.txt (rank 0) when all passed.
"""
import sys

import numpy as np


def main():
    from mpi4py import MPI

    from kapsel.mesh.regrid import to_oblique, to_rectangular
    from kapsel.mesh.pencil import PencilGrid
    from kapsel.particles.profile import Stencil, lees_edwards_profiles
    px, py = int(sys.argv[1]), int(sys.argv[2])
    comm = MPI.COMM_WORLD
    shape, dx = (24, 20, 8), 0.5
    grid = PencilGrid(shape, dx, comm, (px, py))
    rng = np.random.default_rng(5)            # the same whole fields on every rank
    checked = 0
    for g, origin in ((0.37, 10.0), (-0.5, 10.0), (0.0, 10.0), (1.25, 3.0)):
        for method in ("linear", "spline"):
            for f in (rng.standard_normal(shape), rng.standard_normal((3,) + shape)):
                for fun, name in ((to_rectangular, "to_rectangular"),
                                  (to_oblique, "to_oblique")):
                    want = grid.local_real(fun(f, g, method, origin))
                    got = getattr(grid, name)(grid.local_real(f), g, method, origin)
                    assert got.shape == want.shape, (name, got.shape, want.shape)
                    assert np.array_equal(got, want), (name, g, method,
                                                       np.abs(got - want).max())
                    checked += 1
    st = Stencil(2.0, 1.0, dx)
    L = np.array(shape) * dx
    n = 400
    R = rng.uniform(0.0, 1.0, (n, 3)) * L
    R[: n // 4, 1] = rng.uniform(0.0, 2.5, n // 4)            # near y = 0 and y = Ly
    R[n // 4: n // 2, 1] = L[1] - rng.uniform(1e-9, 2.5, n // 4)
    R[:8, 0] = L[0] - 1e-12                                    # at the x boundary
    excluded = pairs = 0
    for offset in (0.0, 1.3, -4.75, 7.0, 0.5 * L[0], 13.1):
        T = grid.near_rows(R, st.offsets, dx, images=offset) if offset else None
        if offset == 0.0:
            T = grid.near_rows(R, st.offsets, dx)
        idx, phi, _ = lees_edwards_profiles(R, st, shape, dx, offset)
        _, _, on = grid.cut_stencils(idx, phi)
        meets = np.flatnonzero(on.any(axis=1))
        assert set(meets.tolist()) <= set(T.tolist()), ("a stencil on the block is missed",
                                                        offset)
        # the stencil's box (lo..hi along x and y) of each returned row meets the block:
        # every point of the box, as lees_edwards_profiles would place it
        lo = st.offsets.min(axis=0)
        hi = st.offsets.max(axis=0)
        box = np.stack(np.meshgrid(*[np.arange(a, b + 1) for a, b in zip(lo, hi)],
                                   indexing="ij"), axis=-1).reshape(-1, 3)

        class Box:
            A, xi = st.A, st.xi
            size = len(box)
            offsets = box
            o = [np.ascontiguousarray(box[:, c]) for c in range(3)]
            of = [np.ascontiguousarray(box[:, c].astype(float)) for c in range(3)]
        bidx, bphi, _ = lees_edwards_profiles(R, Box, shape, dx, offset)
        _, _, bon = grid.cut_stencils(bidx, bphi)
        assert set(T.tolist()) <= set(np.flatnonzero(bon.any(axis=1)).tolist()), \
            ("a row whose stencil box misses the block", offset)
        excluded += n - len(T)
        # the halos of the particle table: every rank's stencils and pair partners
        from kapsel.frame import lees_edwards_displacement
        from kapsel.particles.ownership import Owned
        me = comm.Get_rank()
        for cutoff in (0.0, 2.7):
            o = Owned(grid, st.offsets, dx, cutoff, images=lambda: offset)
            b = o.base(R)
            dest = o.destinations(b, R)
            assert set(meets.tolist()) <= set(np.flatnonzero(dest[:, me]).tolist()), \
                ("a stencil on the block has no copy here", offset, cutoff)
            if cutoff:
                mine = np.flatnonzero(o.owners(b) == me)
                dr = lees_edwards_displacement(R[None, :, :] - R[mine][:, None, :], L,
                                               offset)
                close = np.sqrt((dr * dr).sum(axis=-1)) < cutoff
                need = np.flatnonzero(close.any(axis=0))
                assert set(need.tolist()) <= set(np.flatnonzero(dest[:, me]).tolist()), \
                    ("a pair partner has no copy here", offset)
                pairs += int(close.sum())
    assert excluded > 0 and pairs > 0
    total = comm.allreduce(checked)
    if comm.Get_rank() == 0:
        with open("ok.txt", "w") as fh:
            fh.write(f"{total} re-griddings\n")


if __name__ == "__main__":
    main()
