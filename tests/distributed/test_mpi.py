"""Distributed runs (kapsel.parallel, docs/distributed.md): ``mpiexec -n P kapsel-py``
agrees with the serial run to round-off, restarts interchange between distributed and serial
runs, types that do not run distributed are refused with more than one rank.

The runs are started with the mpiexec of the `mpi` extra (PyPI's mpich wheel, next to the
Python of the venv); 4 ranks oversubscribe a 2-core machine, which is fine for correctness.
Measured (16^3, 4 particles with thermal noise, 50 + 1 steps, 2026-11-29, ``pytest -s -k
agree``): max |distributed - serial| is 0 (bit-identical) with 1 rank; with 2 ranks (slab)
5.9e-14 in the restart's particle table (values up to 15), 1.1e-14 in u_hat (up to 25),
1.1e-16 in R_raw; with 4 ranks (2 x 2 pencils) 3.1e-14, 1.9e-14, 1.1e-16.
"""
import os
import subprocess
import sys

import numpy as np
import pytest

from udf import UDFManager

from builders import (agree_with_serial, cli, continue_distributed, copy_schema, differences,
                      make_input, MPIEXEC, mpirun, saved_data)


pytestmark = pytest.mark.skipif(
    MPIEXEC is None, reason="the mpi extra (mpi4py + an MPI library with mpiexec) is not "
                            "installed: pip install 'kapsel-py[mpi]'")


def test_distributed_runs_agree_with_the_serial_run(tmp_path):
    """50 steps (+ the one after the last snapshot) with 4 particles and thermal noise: 1,
    2 (slab) and 4 (2 x 2 pencils) ranks against the serial run."""
    kw = dict(particles=4, gts=10, nsnap=5)
    ser = make_input(tmp_path / "serial", "Navier_Stokes", **kw)
    assert cli(tmp_path / "serial", ser) == 0
    assert saved_data(str(tmp_path / "serial" / "restart.udf"))["jikan"][0] == 50

    def make(n):
        make_input(tmp_path / f"p{n}", "Navier_Stokes", **kw)
        return tmp_path / f"p{n}"
    agree_with_serial(tmp_path / "serial", make, "4 particles", 1e-11,   # really distributed:
                      moved=lambda diff: diff["Particles"] > 0 or diff["state:u_hat"] > 0)
    # the same input, seed and process grid: the same bits (MPI reduces in a fixed order)
    d = tmp_path / "p4_again"
    make_input(d, "Navier_Stokes", **kw)
    mpirun(d, 4, "input.udf", "-X2", "-Y2")
    again = differences(str(tmp_path / "p4"), str(d))
    assert max(again.values()) == 0.0, again


def test_particles_coupled_only_where_their_stencils_are(tmp_path):
    """32^3 on 4 slabs of 8 planes: a particle's stencil (13 planes for A = 4, XI = 2)
    meets 2 or 3 of the 4 ranks, so each rank couples a proper subset of the 8 particles
    (kapsel.particles.spm: _near, masses from the base point's rank); 20 steps agree with
    the serial run to round-off."""
    kw = dict(particles=8, gts=10, nsnap=2, npx=5)
    ser = make_input(tmp_path / "serial", "Navier_Stokes", **kw)
    assert cli(tmp_path / "serial", ser) == 0
    d = tmp_path / "p4"
    make_input(d, "Navier_Stokes", **kw)
    mpirun(d, 4, "input.udf", "-X4", "-Y1")
    diff = differences(str(tmp_path / "serial"), str(d))
    print(f"32^3, 4 slabs: max |distributed - serial| {diff}")
    assert 0 < max(diff.values()) < 1e-11, diff


def test_restarts_interchange_between_distributed_and_serial_runs(tmp_path):
    """A restart written by a 2-rank run continues serially, and a serial one on 2 ranks;
    both end where a serial run of the whole length does (to round-off)."""
    one = make_input(tmp_path / "one", "Navier_Stokes", nsnap=4)
    assert cli(tmp_path / "one", one) == 0
    d = tmp_path / "dist_then_serial"
    make_input(d, "Navier_Stokes", nsnap=2)
    mpirun(d, 2, "input.udf")
    continue_distributed(d, 0, 4)
    e = tmp_path / "serial_then_dist"
    inp = make_input(e, "Navier_Stokes", nsnap=2)
    assert cli(e, inp) == 0
    continue_distributed(e, 2, 4)
    for x in (d, e):
        assert saved_data(str(x / "restart.udf"))["jikan"][0] == 8
        diff = differences(str(tmp_path / "one"), str(x))
        assert max(diff.values()) < 1e-11, (x.name, diff)


def test_process_grid_must_match_the_ranks(tmp_path):
    d = tmp_path / "grid"
    make_input(d, "Navier_Stokes")
    r = mpirun(d, 2, "input.udf", "-X2", "-Y2", check=False)
    assert r.returncode == 2
    assert "-X2 -Y2 does not match the 2 rank(s)" in r.stderr
    assert not (d / "output.udf").exists()


def test_serial_run_takes_a_one_rank_process_grid(tmp_path):
    """-X1 -Y1 without mpirun (the original's flags for one process): a plain run."""
    d = tmp_path / "x1"
    make_input(d, "Navier_Stokes", nsnap=1)
    code = ("import sys; from kapsel.cli import main; "
            "rc = main(['-Iinput.udf', '-Ooutput.udf', '-Ddefine.udf', '-Rrestart.udf', "
            "'--quiet', '--seed', '1', '-X1', '-Y1']); "
            "assert 'mpi4py' not in sys.modules, 'a plain run imported mpi4py'; sys.exit(rc)")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "OMPI_"))}
    r = subprocess.run([sys.executable, "-c", code], cwd=d, capture_output=True, text=True,
                       env=env, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (d / "restart.udf").exists()


def _table(path):
    rows = [line.split() for line in open(path) if line.strip() and not line.startswith("#")]
    return np.array(rows, dtype=float)


@pytest.mark.parametrize("eq,rate,ranks", [
    ("Shear_Navier_Stokes", 0.02, 2),
    pytest.param("Shear_Navier_Stokes_Lees_Edwards", 0.25, 2, marks=pytest.mark.slow),
    ("Shear_Navier_Stokes_Lees_Edwards", 0.25, 4)])
def test_sheared_types_distributed(tmp_path, eq, rate, ranks):
    """The sheared spectral types on 2 (slab) and 4 (2 x 2) ranks against the serial run,
    50 steps with 4 particles: the restart data, the records, the original's stress table
    shear_stress.dat and the gathered field files (AVS EXTENDED: HDF5).  The Lees-Edwards rate makes the
    frame re-map once (strain 0.77 > 1/2), the distributed re-mapping included.  ~35 s each
    on the shared 2-core machine; the 2-rank Lees-Edwards case is marked slow (the 4-rank
    case covers the same code)."""
    from builders import shear_input
    dirs = {}
    for name, n in (("serial", 0), ("dist", ranks)):
        d = tmp_path / name
        p = shear_input(d, particles=4, rate=rate, gts=10, nsnap=5, eq=eq)
        u = UDFManager(p)
        u.put("ON", "output.AVS")
        u.write(p)
        s = open(p).read().replace("{0,8,4},{0,8,4},{0,8,4}", "{0,4,4},{0,4,4},{0,4,4}")
        open(p, "w").write(s)
        if n:
            r = mpirun(d, n, "input.udf", *(("-X2", "-Y2") if n == 4 else ()))
            out, err = r.stdout, r.stderr
        else:
            code = ("import sys; from kapsel.cli import main; sys.exit(main(['-Iinput.udf', "
                    "'-Ooutput.udf', '-Ddefine.udf', '-Rrestart.udf', '--seed', '11', "
                    "'--quiet']))")
            r = subprocess.run([sys.executable, "-c", code], cwd=d, capture_output=True,
                               text=True, timeout=600)
            assert r.returncode == 0, r.stderr[-2000:]
            out, err = r.stdout, r.stderr
        (d / "table.txt").write_text(out)      # the Lees-Edwards types' per-step table
        dirs[name] = d
    diff = differences(str(dirs["serial"]), str(dirs["dist"]))
    print(f"{eq}, {ranks} ranks: max |distributed - serial| {diff}")
    assert max(diff.values()) < 1e-10, diff
    if "Lees_Edwards" in eq:
        state = saved_data(str(dirs["dist"] / "restart.udf"))
        assert state["state:remaps"] == "1"
        ta, tb = _table(dirs["serial"] / "table.txt"), _table(dirs["dist"] / "table.txt")
        assert ta.shape == tb.shape and ta.shape[0] >= 50
        np.testing.assert_allclose(tb, ta, rtol=1e-6, atol=1e-12)
    sa, sb = _table(dirs["serial"] / "shear_stress.dat"), _table(dirs["dist"] / "shear_stress.dat")
    assert sa.shape == sb.shape == (6, 5)
    np.testing.assert_allclose(sb, sa, rtol=1e-9, atol=1e-14)
    import h5py

    def walk(group, out, pre=""):
        for k, v in group.items():
            if isinstance(v, h5py.Group):
                walk(v, out, pre + k + "/")
            else:
                out[pre + k] = v[...]
    fa, fb = {}, {}
    with h5py.File(dirs["serial"] / "output" / "data.h5") as a, \
            h5py.File(dirs["dist"] / "output" / "data.h5") as b:
        walk(a, fa)
        walk(b, fb)
    assert fa.keys() == fb.keys() and len(fa) > 10
    for k in fa:
        np.testing.assert_allclose(fb[k], fa[k], rtol=1e-5, atol=1e-6, err_msg=k)


def test_walls_are_refused_with_more_than_one_rank(tmp_path):
    """Flat walls (ex14's input with Navier_Stokes) are not distributed: refused by name."""
    from builders import EX14, wall_run_input
    copy_schema(tmp_path, EX14)
    (tmp_path / "in.udf").write_text(wall_run_input(tmp_path, "Navier_Stokes"))
    r = mpirun(tmp_path, 2, "in.udf", check=False)
    assert r.returncode == 2
    assert "switch.wall (flat walls) does not run distributed" in r.stderr
    assert not (tmp_path / "output.udf").exists()


def test_walls_on_one_rank_run_as_a_plain_run(tmp_path):
    """``mpirun -n 1`` of an input that does not run distributed (flat walls) is a plain
    run (docs/distributed.md, "Which types"): the same restart as the run without mpirun.  It stopped
    with a traceback ("walls do not run distributed") before."""
    from builders import EX14, wall_run_input
    for name in ("plain", "one"):
        d = tmp_path / name
        d.mkdir()
        copy_schema(d, EX14)
        (d / "in.udf").write_text(wall_run_input(d, "Navier_Stokes"))
    assert cli(tmp_path / "plain", "in.udf") == 0
    r = mpirun(tmp_path / "one", 1, "in.udf", check=False)
    assert r.returncode == 0, r.stderr[-2000:]
    assert max(differences(str(tmp_path / "plain"), str(tmp_path / "one")).values()) == 0.0


@pytest.mark.parametrize("kind", ["chains", "rigid"])
def test_chains_and_rigid_bodies_distributed(tmp_path, kind):
    """Chains (with noise) and rigid bodies (one free, one with a fixed velocity, gravity)
    on 2 ranks against the serial run, 20 steps: chain beads are owned by ranks (their
    bonds across ranks through ghosts); rigid bodies are owned whole, with their beads, by
    the owner of their first bead (tests/distributed/test_mpi_particles.py)."""
    if kind == "chains":
        from builders import chain_input as make
        args = dict(specs=((4, 2), (3, 1)), output__GTS=10, output__Num_snap=2,
                    constitutive_eq__Navier_Stokes__kBT=0.5)
        name = "chain.udf"
    else:
        from builders import FREE3, rigid_input as make
        args = dict(specs=[FREE3, (2, 1, 1.0, "fix", (0, 0, 0), (0, 0, 0.02))],
                    gravity__G=0.002, gravity__G_direction="-Z", output__GTS=10,
                    output__Num_snap=2)
        name = "rigid.udf"
    for d in ("serial", "dist"):
        (tmp_path / d).mkdir()
        make(tmp_path / d, **args)
    assert cli(tmp_path / "serial", name) == 0
    mpirun(tmp_path / "dist", 2, name)
    diff = differences(str(tmp_path / "serial"), str(tmp_path / "dist"))
    print(f"{kind}, 2 ranks: max |distributed - serial| {diff}")
    assert max(diff.values()) < 1e-10, diff


def test_a_distributed_run_that_blows_up_stops_on_every_rank(tmp_path):
    """A huge gravity (G = 1e12) blows the particles up: every rank stops (no rank left
    waiting in a collective), exit 1, rank 0 says what the plain run says (once), the
    restart of the initial snapshot is kept."""
    said = {}
    for name, n in (("serial", 0), ("dist", 2)):
        d = tmp_path / name
        make_input(d, "Navier_Stokes", gts=2, nsnap=3, kBT=0.0, particles=4)
        u = UDFManager(str(d / "input.udf"))
        u.put(1e12, "gravity.G")
        u.put(2.0, "object_type.spherical_particle.Particle_spec[0].MASS_RATIO")
        u.write(str(d / "input.udf"))
        if n:
            r = mpirun(d, n, "input.udf", check=False)
        else:
            r = subprocess.run([sys.executable, "-m", "kapsel.cli", "-Iinput.udf",
                                "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--seed", "11",
                                "--quiet"], cwd=d, capture_output=True, text=True, timeout=300)
        assert r.returncode == 1, r.stderr[-2000:]
        said[name] = [line for line in r.stderr.splitlines() if "error" in line]
        said[name + " restart"] = list(saved_data(str(d / "restart.udf"))["jikan"])
    assert len(said["dist"]) == 1 and "the run stopped at step" in said["dist"][0]
    assert said["dist"] == said["serial"]
    assert said["dist restart"] == said["serial restart"] == [-1.0, 0.0]   # the initial state


def test_a_launcher_of_another_mpi_is_refused(tmp_path):
    """Started by an mpirun that is not that of mpi4py's MPI library, each process would see
    one rank and run the whole input alone: refused (the launcher's PMI_SIZE says 2)."""
    d = tmp_path / "other"
    make_input(d, "Navier_Stokes")
    env = dict(os.environ, PMI_SIZE="2")
    r = subprocess.run([sys.executable, "-m", "kapsel.cli", "-Iinput.udf", "-Ooutput.udf",
                        "-Ddefine.udf", "-Rrestart.udf", "--quiet"], cwd=d, env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2
    assert "started by an MPI launcher for 2 ranks, but the MPI library of mpi4py sees 1" \
        in r.stderr
    assert not (d / "output.udf").exists()
