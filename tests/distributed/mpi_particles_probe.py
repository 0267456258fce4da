"""Run under mpiexec by tests/distributed/test_mpi_particles.py: build the model of ``input.udf`` in the
current directory as ``kapsel-py`` does (kapsel.cli.prepare), advance it ``steps`` steps and
check after every step that the particles are owned by ranks as kapsel.particles.ownership
says; writes probe.npz (rank 0) with the gathered final particle table and the statistics.

    mpiexec -n P python mpi_particles_probe.py STEPS [-X px -Y py]

Checks, every step, on every rank (failures raise, which ends every rank):
* each particle is owned by exactly one rank, the owned counts add up to N, the owner is
  the rank whose block holds the stencil's base point (spm ``_near``'s ``own``); for rigid
  bodies that of the body's first bead, every body whole on its owner (all its beads
  owned there, its state in the owner's local bodies);
* a rank holds its owned particles and ghosts only: the owned rows first, no duplicates;
* every particle whose stencil meets the rank's block (spm ``_near``, independent of the
  halo code) and every pair partner (within the pair cutoff, kapsel.particles.cells) of an
  owned particle is there.
"""
import sys

import numpy as np



def _base_here(spm, R):
    """Whether the stencil's base point floor(R / DX) (on the rectangular grid, where the
    profiles are built, sheared runs too) of each particle lies in this rank's block: who
    must own it."""
    s = np.asarray(R, dtype=float) / spm.dx
    b = np.floor(s).astype(np.int64)
    here = np.ones(len(s), dtype=bool)
    for axis in (0, 1):
        a0, a1 = spm.layout.real_range[axis]
        base = np.mod(b[:, axis], spm.shape[axis])
        here &= (base >= a0) & (base < a1)
    return here

def main():
    from kapsel.cli import build_parser, prepare
    from kapsel.parallel import start
    from kapsel.particles.cells import pairs_within
    steps = int(sys.argv[1])
    args = build_parser().parse_args(["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf",
                                      "-Rrestart.udf", "--seed", "11", "--quiet",
                                      *sys.argv[2:]])
    args.dist = start(args)
    prepared = prepare(args)
    assert not isinstance(prepared, int), prepared
    model = prepared[2]
    spm = model.spm
    o = spm.owned
    assert o is not None, "the particles are not owned by ranks"
    comm = o.comm
    N = spm.n_global
    cutoff = spm.forces.cutoff if spm.forces is not None else 0.0
    owners_of, local_counts, ghost_counts, owned_counts = [], [], [], []
    for step in range(steps + 1):
        if step:
            model.advance()
        p, n = spm.p, o.n_own
        gid = o.gid
        assert len(gid) == p.n and len(np.unique(gid)) == p.n, "duplicate rows"
        assert np.all(o.owner[:n] == o.me) and np.all(o.owner[n:] != o.me)
        assert np.all(np.diff(gid[:n]) > 0), "owned rows not in global-id order"
        assert np.array_equal(spm._T[:n], np.arange(n)), "an owned row has no profile"
        # the whole table (every rank): owned rows gathered
        all_gid = np.concatenate(comm.allgather(gid[:n]))
        all_R = np.concatenate(comm.allgather(p.R[:n]))
        assert len(all_gid) == N and np.array_equal(np.sort(all_gid), np.arange(N)), \
            "a particle is owned by no rank or by two"
        R = np.empty((N, 3))
        R[all_gid] = all_R
        # the profiles' grid: rectangular, under Lees-Edwards images in a sheared run
        images = spm.fluid.image_offset if spm.oblique else 0.0
        T = spm.layout.near_rows(R, spm.stencil.offsets, spm.dx, images=images)
        own = _base_here(spm, R[T])
        assert set(T.tolist()) <= set(gid.tolist()), "a particle meeting the block is missing"
        bodies = spm._bodies
        if bodies is not None:           # owned with their first bead, whole
            lead = bodies.first_beads()
            mine_b = np.flatnonzero(_base_here(spm, R[lead]))
            assert set(mine_b.tolist()) == set(bodies.body[gid[:n]].tolist()), \
                "a body is not owned by the owner of its first bead"
            assert np.array_equal(np.sort(np.flatnonzero(np.isin(bodies.body, mine_b))),
                                  gid[:n]), "a body is not whole on its owner"
            assert np.array_equal(spm.motion.global_bodies, np.sort(mine_b))
            assert spm.motion.state.n == len(mine_b)
        else:
            assert set(T[own].tolist()) == set(gid[:n].tolist()), \
                "owner is not the base point's"
        if cutoff > 0:      # pairs as kapsel.particles.forces finds them (oblique x - g y),
            gs = spm.fluid.frame_strain if spm.oblique else 0.0   # within the cutoff
            Ro = R.copy()
            Ro[:, 0] = np.mod(R[:, 0] - gs * R[:, 1], spm.box[0])
            i, j, dr = pairs_within(Ro, spm.box, cutoff * (1.0 + abs(gs)))
            dr = np.array(dr, dtype=float).reshape(-1, 3)
            dr[:, 0] += gs * dr[:, 1]
            keep = np.sqrt((dr * dr).sum(axis=1)) < cutoff
            i, j = i[keep], j[keep]
            if bodies is not None:                 # no pair forces within a body
                keep = bodies.body[i] != bodies.body[j]
                i, j = i[keep], j[keep]
            mine = np.zeros(N, dtype=bool)
            mine[gid[:n]] = True
            need = np.union1d(j[mine[i]], i[mine[j]])
            assert set(need.tolist()) <= set(gid.tolist()), "a pair partner is missing"
        owner = np.empty(N, dtype=np.int64)
        owner[all_gid] = np.concatenate([np.full(k, r) for r, k in
                                         enumerate(comm.allgather(n))])
        owners_of.append(owner)
        local_counts.append(comm.allgather(p.n))
        owned_counts.append(comm.allgather(n))
        ghost_counts.append(comm.allgather(p.n - n))
    remaps = int(getattr(spm.fluid, "remaps", 0))
    whole = model.particles
    spm.gather()
    extra = {}
    if spm._bodies is not None:
        st = spm._bodies.state
        extra = {f"body_{k}": getattr(st, k).copy() for k in ("R", "R_raw", "v", "omega", "q")}
    if o.me == 0:
        np.savez("probe.npz", **extra, R=whole.R, v=whole.v, omega=whole.omega, R_raw=whole.R_raw,
                 f_hydro=whole.f_hydro, owners=np.array(owners_of),
                 local=np.array(local_counts), owned=np.array(owned_counts),
                 ghosts=np.array(ghost_counts), N=N, remaps=remaps)


if __name__ == "__main__":
    main()
