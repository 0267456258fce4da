"""Particles owned by ranks in distributed runs (kapsel.particles.ownership,
docs/distributed.md): each particle is owned by the rank whose block holds its stencil's base
point, the other ranks that need it (its profile meets their block, or it is a pair partner
of one of their particles) hold a ghost copy; particles migrate between ranks; the runs agree
with the serial run to round-off and repeat bit for bit.

Measured (2026-11-29, ``pytest -s tests/distributed/test_mpi_particles.py``): 32^3 with 12 interacting
particles, max |distributed - serial| 7.1e-14 (particle table) / 4.1e-14 (u_hat) on 2
ranks, 5.7e-14 / 4.6e-14 on 2 x 2, 0 on 1 rank; particles migrating through 4 slabs:
|4 ranks - 1 rank| 0 in R, 1.1e-16 in v, 1.8e-14 in F_H; chains on 4 slabs 8.9e-16 in R,
2.7e-14 in F_H; Lees-Edwards on 2 x 2 with a frame re-mapping 2.2e-16 in R, 2.2e-14 in F_H
(2026-12-02: the particles coupled on the rectangular grid, distributed and plain alike).
Rigid bodies (owned whole by the owner of their first bead), 50 steps, 2 / 2 x 2 ranks:
5.7e-14 / 5.9e-14 (Navier_Stokes), 8.5e-14 / 7.1e-14 (Shear_Navier_Stokes), 5.7e-14 /
1.7e-13 (Lees-Edwards), 0 on 1 rank; falling through 4 slabs 2.1e-14 in F_H, 0 in the
bodies' R; restarts interchanged 6.4e-14 (Navier_Stokes) / 1.2e-13
(Lees-Edwards); dipoles (distributed Ewald): Quincke
rollers 1.4e-14 / 7.1e-15, FIXED dipoles under Lees-Edwards 1.1e-14 / 1.4e-14;
self-propelled (squirmers, tumbler, obstacle) 6.4e-14 / 2.1e-13 (Navier_Stokes), 1.4e-13 /
1.6e-13 (Shear_Navier_Stokes).
Each test takes 5-25 s on the busy 2-core machine.
"""
import os
import subprocess
import sys

import numpy as np
import pytest
from udf import UDFManager

from builders import agree_with_serial, cli, differences, make_input, MPIEXEC, mpirun, sample_input


pytestmark = pytest.mark.skipif(MPIEXEC is None, reason="the mpi extra is not installed")
PROBE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "mpi_particles_probe.py")


def test_owned_particles_agree_with_the_serial_run(tmp_path):
    """32^3, 12 particles (A = 4) with thermal noise and the full LJ attraction (LJ_truncate
    OFF: range min(2.5 sigma, half the box) = 16, so pairs interact across the block
    boundaries), 50 + 1 steps
    on 1, 2 (slabs) and 4 (2 x 2 pencils) ranks against the serial run; the 2-rank run
    repeated gives the same bits."""
    kw = dict(particles=12, gts=10, nsnap=5, npx=5)
    ser = make_input(tmp_path / "serial", "Navier_Stokes", **kw)
    assert cli(tmp_path / "serial", ser) == 0

    def make(n):
        make_input(tmp_path / f"p{n}", "Navier_Stokes", **kw)
        return tmp_path / f"p{n}"
    agree_with_serial(tmp_path / "serial", make, "32^3, 12 particles", 1e-11)
    d = tmp_path / "p2_again"
    make_input(d, "Navier_Stokes", **kw)
    mpirun(d, 2, "input.udf")
    again = differences(str(tmp_path / "p2"), str(d))
    assert max(again.values()) == 0.0, again


def _drift_input(d, n=12, x=None):
    """128 x 16 x 16, A = 2, XI = 1, WCA pairs (LJ_truncate ON), gravity along -X on
    heavier particles (MASS_RATIO 3) in a row along x, some just above a block boundary
    (x = 32, 64, 96 for 4 slabs), a few pairs close enough to interact."""
    u = sample_input(d, "Navier_Stokes")
    u.put(7, "mesh.NPX")
    u.put(2.0, "A")
    u.put(1.0, "A_XI")
    u.put("ON", "switch.LJ_truncate")
    u.put(0.5, "constitutive_eq.Navier_Stokes.kBT")
    u.put(n, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put(3.0, "object_type.spherical_particle.Particle_spec[0].MASS_RATIO")
    u.put(0.5, "gravity.G")
    u.put("-X", "gravity.G_direction")
    x = x or [32.2, 36.8, 64.15, 68.7, 96.2, 100.9, 8.0, 20.0, 45.0, 80.0, 112.0, 124.0][:n]
    rows = np.zeros((n, 13))
    rows[:, 0] = x
    rows[:, 1] = [4.0 + 8.0 * (k % 2) for k in range(n)]
    rows[:, 2] = [4.0 + 8.0 * ((k // 2) % 2) for k in range(n)]
    if n >= 6:
        rows[:, 1][[1, 3, 5]] = rows[:, 1][[0, 2, 4]]      # pairs 0-1, 2-3, 4-5: 4.5 apart
        rows[:, 2][[1, 3, 5]] = rows[:, 2][[0, 2, 4]]
    rows[:, 6] = 1.0
    u.put("user_specify", "switch.INIT_distribution.type")
    u.put(rows, "switch.INIT_distribution.user_specify.Particles[]")
    u.put(10, "output.GTS")
    u.put(1, "output.Num_snap")
    u.write(os.path.join(d, "input.udf"))


def _probe(d, n, steps, *grid):
    cmd = [MPIEXEC, "-n", str(n), sys.executable, PROBE, str(steps), *grid]
    r = subprocess.run(cmd, cwd=d, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    with np.load(os.path.join(d, "probe.npz")) as z:
        return {k: z[k] for k in z.files}


def _one_and_four_slabs(ref, dist):
    """The probe's 30 steps in ``ref`` on 1 rank and in ``dist`` on 4 slabs (-X4): (their
    records, the particle count N, the particles whose owner changed); every particle is
    owned once after every step."""
    a = _probe(ref, 1, 30)
    b = _probe(dist, 4, 30, "-X4", "-Y1")
    N = int(b["N"])
    assert np.all(b["owned"].sum(axis=1) == N)
    moved = np.flatnonzero(np.any(b["owners"] != b["owners"][0], axis=0))
    return a, b, N, moved


def test_particles_are_owned_by_ranks_and_migrate(tmp_path):
    """12 particles falling along -X through 4 slabs of 32 planes (128 x 16 x 16), 30 steps:
    after every step each particle is owned by exactly one rank (that of its stencil's base
    point), the owned counts add up to N, each rank holds its owned particles and ghosts
    only, and every particle whose profile meets its block and every pair partner of its
    particles (the probe, tests/distributed/mpi_particles_probe.py); particles cross block boundaries
    (their owner changes) and end where the 1-rank run has them (their whole state
    travelled with them).  A rank holds about 40 % of the particles."""
    ref, dist = tmp_path / "one", tmp_path / "four"
    for d in (ref, dist):
        _drift_input(d)
    a, b, N, moved = _one_and_four_slabs(ref, dist)
    print(f"owners changed for particles {moved.tolist()}; particles held per rank: "
          f"max {b['local'].max()} of {N}, mean {b['local'].mean():.1f} "
          f"(ghosts mean {b['ghosts'].mean():.1f})")
    assert len(moved) >= 3
    assert b["local"].max() < 0.75 * N and b["local"].mean() < 0.5 * N
    for k in ("R", "v", "omega", "R_raw", "f_hydro"):
        dev = float(np.abs(a[k] - b[k]).max())
        print(f"  max |4 ranks - 1 rank| {k}: {dev:.3g}")
        assert dev < 1e-11, k
    assert np.all(a["R_raw"][:, 0] < np.array([32.2, 36.8, 64.15, 68.7, 96.2, 100.9, 8.0,
                                               20.0, 45.0, 80.0, 112.0, 124.0]))


def test_chains_owned_by_ranks(tmp_path):
    """3 chains of 6 beads (A = 2, bond 2 A, FENE + WCA, noise) in 64 x 16 x 16 on 4 slabs of
    16 planes, 20 steps: the bond partners of a rank's beads are there (the halo is at
    least the FENE R0 = 3 A, longer than any bond: the run stops at 0.99 R0), ownership
    holds after every step (the probe), and the beads end where the 1-rank run has them."""
    from builders import chain_input
    got = {}
    for name, n, grid in (("one", 1, ()), ("four", 4, ("-X4", "-Y1"))):
        d = tmp_path / name
        d.mkdir()
        path = chain_input(d, specs=((6, 3),), A=2.0, A_XI=1.0, mesh__NPX=6, mesh__NPY=4,
                           mesh__NPZ=4, constitutive_eq__Navier_Stokes__kBT=0.5,
                           output__GTS=10, output__Num_snap=1)
        os.replace(path, d / "input.udf")
        got[name] = _probe(d, n, 20, *grid)
    a, b = got["one"], got["four"]
    print(f"chains: beads held per rank: max {b['local'].max()} of {int(b['N'])}, mean "
          f"{b['local'].mean():.1f}")
    assert b["local"].max() < int(b["N"])
    for k in ("R", "v", "omega", "R_raw", "f_hydro"):
        dev = float(np.abs(a[k] - b[k]).max())
        print(f"  max |4 ranks - 1 rank| {k}: {dev:.3g}")
        assert dev < 1e-11, k


def test_lees_edwards_particles_owned_by_ranks(tmp_path):
    """Shear_Navier_Stokes_Lees_Edwards, 32^3 on 2 x 2 ranks, 10 particles (A = 2, XI = 1,
    WCA, noise), 50 steps at shear rate 0.25 (the frame re-maps once): ownership follows the
    base point on the rectangular grid (where the profiles are built), halos cover the
    Lees-Edwards images of the stencils and of the pair partners (the probe, after every
    step), and the run ends where the 1-rank run does.  (Every rank holds all 10 particles
    here; the halo geometry under the images is tested in tests/distributed/test_mpi_layout.py.)"""
    from builders import shear_input
    got = {}
    for name, n, grid in (("one", 1, ()), ("four", 4, ("-X2", "-Y2"))):
        d = tmp_path / name
        path = shear_input(d, particles=10, rate=0.25, gts=10, nsnap=1, npx=5)
        u = UDFManager(path)
        u.put(2.0, "A")
        u.put(1.0, "A_XI")
        u.put("ON", "switch.LJ_truncate")
        u.put(0.5, "constitutive_eq.Shear_Navier_Stokes_Lees_Edwards.kBT")
        u.write(path)
        got[name] = _probe(d, n, 50, *grid)
    a, b = got["one"], got["four"]
    assert int(b["remaps"]) == 1
    moved = np.flatnonzero(np.any(b["owners"] != b["owners"][0], axis=0))
    print(f"Lees-Edwards: owners changed for {len(moved)} of {int(b['N'])} particles; held "
          f"per rank: max {b['local'].max()}, mean {b['local'].mean():.1f}")
    assert len(moved) >= 1
    for k in ("R", "v", "omega", "R_raw", "f_hydro"):
        dev = float(np.abs(a[k] - b[k]).max())
        print(f"  max |4 ranks - 1 rank| {k}: {dev:.3g}")
        assert dev < 1e-10, k


def test_lees_edwards_ranks_without_particles(tmp_path):
    """Shear_Navier_Stokes_Lees_Edwards, 32^3 on 4 slabs (-X4, 8 planes each), one particle
    (A = 2, XI = 1, no pair forces) in the middle: the outer ranks hold no particle, yet
    take part in the coupling's collectives (the re-gridding of u* and of the increment
    on the gathered x rows, the particle stress moment); the run ends where the 1-rank run
    does."""
    from builders import shear_input
    got = {}
    for name, n, grid in (("one", 1, ()), ("four", 4, ("-X4", "-Y1"))):
        d = tmp_path / name
        path = shear_input(d, particles=1, rate=0.25, gts=10, nsnap=1, npx=5)
        u = UDFManager(path)
        u.put(2.0, "A")
        u.put(1.0, "A_XI")
        u.put("NONE", "switch.LJ_truncate")
        u.put("user_specify", "switch.INIT_distribution.type")
        rows = np.zeros((1, 13))
        rows[0, :3] = (16.3, 16.6, 16.1)
        rows[0, 6] = 1.0
        u.put(rows, "switch.INIT_distribution.user_specify.Particles[]")
        u.write(path)
        got[name] = _probe(d, n, 20, *grid)
    a, b = got["one"], got["four"]
    held = b["local"]                       # (steps + 1, ranks) rows held by each rank
    print(f"one particle on 4 slabs: rows held per rank {held.min(axis=0)}..{held.max(axis=0)}")
    assert held[:, 0].max() == 0 and held[:, 3].max() == 0
    for k in ("R", "v", "omega", "R_raw", "f_hydro"):
        dev = float(np.abs(a[k] - b[k]).max())
        print(f"  max |4 ranks - 1 rank| {k}: {dev:.3g}")
        assert dev < 1e-11, k


def test_pinned_particles_owned_by_ranks(tmp_path):
    """switch.pin (particle 1 held, particle 2's rotation held) on 2 ranks: the pins follow
    the global ids of the particles a rank owns; 20 steps agree with the serial run."""
    kw = dict(particles=6, gts=10, nsnap=2, npx=5)
    dirs = {}
    for name in ("serial", "dist"):
        d = tmp_path / name
        path = make_input(d, "Navier_Stokes", **kw)
        u = UDFManager(path)
        u.put("YES", "switch.pin.type")
        u.put([1], "switch.pin.YES.pin[]")
        u.put([2], "switch.pin.YES.pin_rot[]")
        u.write(path)
        dirs[name] = d
    assert cli(dirs["serial"], "input.udf") == 0
    mpirun(dirs["dist"], 2, "input.udf")
    diff = differences(str(dirs["serial"]), str(dirs["dist"]))
    print(f"pinned, 2 ranks: max |distributed - serial| {diff}")
    assert 0 < max(diff.values()) < 1e-11, diff
    from builders import records
    recs = records(str(dirs["dist"] / "output.udf"))
    first, last = np.asarray(recs[0][1]), np.asarray(recs[-1][1])
    assert np.array_equal(first[1], last[1])                 # the pinned particle stayed
    assert np.abs(first - last).max() > 0                     # the others moved


# ---------------------------------------------------------------- rigid bodies
# bodies of user-specified bead positions (A = 2, beads touching at 2 A = 4), in 128 x 16 x 16,
# their first beads just above the block boundaries x = 64, 32, 0, 96 of 4 slabs: a rod along
# x, an L, a rod along z at the periodic x = 0 face, a rod along y across the y = 0 face
# (the Lees-Edwards images of the sheared type), and a one-bead body 4.3 from the L (WCA
# partners across bodies)
BODIES = [
    [[64.2, 4.0, 4.0], [60.2, 4.0, 4.0], [68.2, 4.0, 4.0]],
    [[32.2, 10.0, 10.0], [36.2, 10.0, 10.0], [32.2, 14.0, 10.0]],
    [[0.2, 8.0, 3.0], [0.2, 8.0, 7.0]],
    [[96.2, 16.3, 12.0], [96.2, 12.3, 12.0], [96.2, 20.3, 12.0]],
    [[36.2, 10.0, 5.7]],
]


def _bodies_input(d, eq="Navier_Stokes", gravity=0.5, kBT=0.5, nx=7, raw=None, **puts):
    """The BODIES above (free, MASS_RATIO 3) falling along -X under gravity with noise."""
    from builders import rigid_input
    os.makedirs(d, exist_ok=True)
    shapes = [3, 3, 2, 3, 1]
    specs = [(k, 1, 3.0, "free", (0, 0, 0), (0, 0, 0)) for k in shapes]
    X = np.array([x for b in BODIES for x in b])
    rows = np.zeros((len(X), 13))
    rows[:, 0:3] = X
    rows[:, 6] = 1.0
    path = rigid_input(d, specs, eq=eq, name="input.udf",
                       raw={"A": 2.0, "A_XI": 1.0, "mesh.NPX": nx, "mesh.NPY": 4,
                            "mesh.NPZ": 4, f"constitutive_eq.{eq}.kBT": kBT,
                            "gravity.G": gravity, "gravity.G_direction": "-X",
                            "switch.INIT_distribution.type": "user_specify",
                            "switch.INIT_distribution.user_specify.Particles[]": rows,
                            **(raw or {})},
                       **puts)
    return path


def test_rigid_bodies_owned_by_ranks_and_migrate(tmp_path):
    """5 rigid bodies (12 beads; rods, an L, one bead) falling along -X through 4 slabs of
    32 planes (128 x 16 x 16), noise on, 30 steps: after every step each body is owned, whole,
    by the rank whose block holds its first bead's base point, a rank holds its owned beads
    and the ghosts of every bead whose profile meets its block or that is a pair partner of
    one of its beads (the probe); bodies change owners keeping their ids and state, and end
    where the 1-rank run has them."""
    ref, dist = tmp_path / "one", tmp_path / "four"
    for d in (ref, dist):
        _bodies_input(d, output__GTS=10, output__Num_snap=1)
    a, b, N, moved = _one_and_four_slabs(ref, dist)
    print(f"bodies: owners changed for beads {moved.tolist()}; beads held per rank: "
          f"max {b['local'].max()} of {N}, mean {b['local'].mean():.1f}")
    assert len(moved) >= 2
    assert b["local"].max() < N and b["local"].mean() < 0.75 * N
    for k in ("R", "v", "omega", "R_raw", "f_hydro", "body_R", "body_R_raw", "body_v",
              "body_omega", "body_q"):
        dev = float(np.abs(a[k] - b[k]).max())
        print(f"  max |4 ranks - 1 rank| {k}: {dev:.3g}")
        assert dev < 1e-11, k
    start = [np.mean(b, axis=0)[0] for b in BODIES]
    assert np.all(a["body_R_raw"][:, 0] < start)                            # they fell


def _body_outputs(d):
    """RigidParticles[] (R, v, omega, q) of every record of output.udf, E of every record
    and the table rotational_energy.dat."""
    doc = UDFManager(str(d / "output.udf"))
    rows, E = [], []
    for n in range(doc.totalRecord()):
        doc.jump(n)
        E.append(doc.get("E"))
        if doc.size("RigidParticles[]"):
            rows.append(np.concatenate([np.ravel(doc.getArray(f"RigidParticles[].{k}"))
                                        for k in ("R", "v", "omega")]))
    assert len(rows) == doc.totalRecord()
    return np.array(rows), np.array(E), np.loadtxt(d / "rotational_energy.dat", ndmin=2)


@pytest.mark.parametrize("eq", ["Navier_Stokes", "Shear_Navier_Stokes",
                                "Shear_Navier_Stokes_Lees_Edwards"])
def test_rigid_bodies_agree_with_the_serial_run(tmp_path, eq):
    """The bodies above, 50 + 1 steps with noise and gravity, on 1, 2 (slabs) and 4 (2 x 2)
    ranks against the serial run (restart data with the bodies' state, output records with
    RigidParticles[] and E, rotational_energy.dat)."""
    puts = dict(output__GTS=10, output__Num_snap=5)
    raw = {}
    if eq != "Navier_Stokes":
        base = f"constitutive_eq.{eq}.External_field"
        raw = {f"{base}.type": "DC",
               f"{base}.DC.Shear_rate": 0.05 if "Lees" in eq else 0.02}
    ser = _bodies_input(tmp_path / "serial", eq=eq, gravity=0.2, raw=raw, **puts)
    assert cli(tmp_path / "serial", os.path.basename(ser)) == 0
    def make(n):
        d = tmp_path / f"p{n}"
        _bodies_input(d, eq=eq, gravity=0.2, raw=raw, **puts)
        return d

    def outputs(d):            # RigidParticles[], E and rotational_energy.dat as written
        diff = {}
        for k, a, b in zip(("RigidParticles", "E", "rotational_energy.dat"),
                           _body_outputs(tmp_path / "serial"), _body_outputs(d)):
            assert a.shape == b.shape
            diff[k] = float(np.abs(a - b).max(initial=0.0))
        return diff
    agree_with_serial(tmp_path / "serial", make, f"{eq}, rigid bodies", 1e-10, outputs)


@pytest.mark.parametrize("eq", ["Navier_Stokes", "Shear_Navier_Stokes_Lees_Edwards"])
def test_rigid_body_restarts_interchange_between_distributed_and_serial_runs(tmp_path, eq):
    """The bodies above: a restart written by a 2 x 2-rank run (gathered beads, the bodies'
    state in the state file) continues serially, a serial one on 2 x 2 ranks; both end where a
    serial run of the whole length does, to round-off."""
    from builders import continue_distributed
    raw = {}
    if eq != "Navier_Stokes":
        base = f"constitutive_eq.{eq}.External_field"
        raw = {f"{base}.type": "DC", f"{base}.DC.Shear_rate": 0.05}
    kw = dict(eq=eq, gravity=0.2, raw=raw, output__GTS=10)
    _bodies_input(tmp_path / "one", output__Num_snap=4, **kw)
    assert cli(tmp_path / "one", "input.udf") == 0
    d = tmp_path / "dist_then_serial"
    _bodies_input(d, output__Num_snap=2, **kw)
    mpirun(d, 4, "input.udf", "-X2", "-Y2")
    continue_distributed(d, 0, 4)
    e = tmp_path / "serial_then_dist"
    _bodies_input(e, output__Num_snap=2, **kw)
    assert cli(e, "input.udf") == 0
    rs = UDFManager(str(e / "restart.udf"))
    rs.put(4, "output.Num_snap")
    rs.write(str(e / "cont.udf"))
    from kapsel.io.restart import state_path
    import shutil
    shutil.copy(state_path(str(e / "restart.udf")), state_path(str(e / "cont.udf")))
    mpirun(e, 4, "cont.udf", "-X2", "-Y2")
    for x in (d, e):
        diff = differences(str(tmp_path / "one"), str(x))
        print(f"{eq}, rigid bodies, {x.name}: max |continued - serial| "
              f"{max(diff.values()):.3g} ({max(diff, key=diff.get)})")
        assert "state:rigid_q" in diff            # the bodies' state went through
        assert max(diff.values()) < 1e-10, (x.name, diff)


# ---------------------------------------------------------------- dipoles, Quincke rollers
@pytest.mark.parametrize("case", ["quincke", "fixed_lees_edwards"])
def test_dipoles_agree_with_the_serial_run(tmp_path, case):
    """Dipoles by the distributed Ewald sum (kapsel.particles.ewald ``dipolar_ewald_owned``:
    real-space part over owned + ghosts, structure sums of the owned particles summed over
    the ranks): ex12 without walls (6 Quincke rollers, one-bead rigid bodies with QUINCKE
    dipoles and the constraint torque, 16^3), and FIXED dipoles on 6 spheres under
    Lees-Edwards shear; noise on, 50 + 1 steps on 1, 2 and 4 (2 x 2) ranks against the
    serial run."""
    from builders import nowall_input
    if case == "quincke":
        eq = "Navier_Stokes"
        puts = {}
    else:
        eq = "Shear_Navier_Stokes_Lees_Edwards"
        puts = dict(switch__quincke__type="OFF", switch__free_rigid__type="NO",
                    object_type__type="spherical_particle",
                    switch__multipole__ON__Dipole__ON__type="FIXED", gravity__G=0.0,
                    **{"object_type__spherical_particle__Particle_spec[]":
                       [[6, 1.5, 0.0, "NONE", "OFF", [0.0, 0, 0], [0.0, 0, 0], 0.0, 0.0, 0.0,
                         0.0]],
                       f"constitutive_eq__{eq}__External_field__DC__Shear_rate": 0.05})
    puts.update({"constitutive_eq__type": eq, f"constitutive_eq__{eq}__kBT": 0.2,
                 "output__GTS": 10, "output__Num_snap": 5, "output__AVS": "OFF",
                 "switch__INIT_orientation": "random"})
    dirs = {}
    for name in ("serial", "p1", "p2", "p4"):
        d = tmp_path / name
        d.mkdir()
        nowall_input(d, name="input.udf", **puts)
        dirs[name] = d
    assert cli(dirs["serial"], "input.udf") == 0
    agree_with_serial(dirs["serial"], lambda n: dirs[f"p{n}"], f"dipoles ({case})", 1e-10)


# ---------------------------------------------------------------- self-propelled particles
@pytest.mark.parametrize("eq", ["Navier_Stokes", "Shear_Navier_Stokes"])
def test_self_propelled_particles_agree_with_the_serial_run(tmp_path, eq):
    """2 squirmers (pushers), a tumbler and an obstacle (tests/validation/test_janus.py's input in
    32 x 32 x 16, noise, the slip iteration to SLIP_tol 1e-3 or 3 passes), 50 + 1 steps on 1, 2 and 4
    (2 x 2) ranks against the serial run: the squirmers' stencil sums and slip forces summed
    on their owners, the iterates sent to the ghosts, the passes decided over all ranks."""
    from builders import janus_input
    from udf import UDFManager
    dirs = {}
    for name in ("serial", "p1", "p2", "p4"):
        d = tmp_path / name
        path = janus_input(d, eq=eq, nsnap=5)
        u = UDFManager(path)
        u.put(10, "output.GTS")
        u.put(4, "mesh.NPZ")                    # 32 x 32 x 16
        if eq != "Navier_Stokes":
            u.put(0.5, f"constitutive_eq.{eq}.kBT")
        u.write(path)
        dirs[name] = d
    assert cli(dirs["serial"], "input.udf") == 0
    agree_with_serial(dirs["serial"], lambda n: dirs[f"p{n}"], f"self-propelled ({eq})",
                      1e-10)
