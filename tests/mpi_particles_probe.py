"""Run under mpiexec by tests/test_mpi_particles.py: build the model of ``input.udf`` in the
current directory as ``kapsel-py`` does (kapsel.cli.prepare), advance it ``steps`` steps and
check after every step that the particles are owned by ranks as kapsel.parallel.particles
says; writes probe.npz (rank 0) with the gathered final particle table and the statistics.

    mpiexec -n P python mpi_particles_probe.py STEPS [-X px -Y py]

Checks, every step, on every rank (failures raise, which ends every rank):
* each particle is owned by exactly one rank, the owned counts add up to N, the owner is
  the rank whose block holds the stencil's base point (spm ``_near``'s ``own``);
* a rank holds its owned particles and ghosts only: the owned rows first, no duplicates;
* every particle whose stencil meets the rank's block (spm ``_near``, independent of the
  halo code) and every pair partner (within the pair cutoff, kapsel.particles.cells) of an
  owned particle is there.
"""
import sys

import numpy as np


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
        g, y0 = ((spm.fluid.frame_strain, spm.fluid.y0) if spm.oblique else (0.0, 0.0))
        T, own = spm._near(R, g, y0)
        assert set(T[own].tolist()) == set(gid[:n].tolist()), "owner is not the base point's"
        assert set(T.tolist()) <= set(gid.tolist()), "a particle meeting the block is missing"
        if cutoff > 0:      # pairs as kapsel.particles.forces finds them (oblique x - g y)
            Ro = R.copy()
            Ro[:, 0] = np.mod(R[:, 0] - g * R[:, 1], spm.box[0])
            i, j, _ = pairs_within(Ro, spm.box, cutoff * (1.0 + abs(g)))
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
    if o.me == 0:
        np.savez("probe.npz", R=whole.R, v=whole.v, omega=whole.omega, R_raw=whole.R_raw,
                 f_hydro=whole.f_hydro, owners=np.array(owners_of),
                 local=np.array(local_counts), owned=np.array(owned_counts),
                 ghosts=np.array(ghost_counts), N=N, remaps=remaps)


if __name__ == "__main__":
    main()
