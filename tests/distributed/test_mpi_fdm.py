"""Distributed runs of the finite-difference types (docs/distributed.md):
``mpiexec -n P kapsel-py`` on Navier_Stokes_FDM, Navier_Stokes_Cahn_Hilliard_FDM and the
Lees-Edwards FDM types agrees with the serial run to round-off (restart data, output.udf
records, the per-snapshot HDF5 files, the stress table), restarts interchange between
distributed and serial runs, a type that does not run distributed is refused by name.

16^3, 4 particles with thermal noise, 50 steps (+ the one after the last snapshot), every
scheme.  Measured (2026-11-29, ``pytest -s tests/distributed/test_mpi_fdm.py -k agree``): see the
``print`` of each case; 1 rank is bit-identical for the explicit schemes (the same stencils;
the implicit ones differ by the order of BiCGSTAB's dot products), 2 (slab) and 4 (2 x 2
pencil) ranks differ by ~1e-16 in u, psi and ~1e-13 in the particle table (values up to 83).
"""
import glob
import os
import sys

import numpy as np
import pytest

from udf import UDFManager  # noqa: E402

from builders import cli, differences, make_input, MPIEXEC, mpirun, saved_data


pytestmark = pytest.mark.skipif(
    MPIEXEC is None, reason="the mpi extra (mpi4py + an MPI library with mpiexec) is not "
                            "installed: pip install 'kapsel-py[mpi]'")

NS, NSCH = "Navier_Stokes_FDM", "Navier_Stokes_Cahn_Hilliard_FDM"
VC = f"constitutive_eq.{NSCH}.NS_solver.implicit_scheme"


def fdm_input(d, eq, ns, ch="explicit_scheme", viscosity_change=False, **kw):
    kw = {"particles": 4, "gts": 10, "nsnap": 5, **kw}
    path = make_input(d, eq, ns=ns, ch=ch, **kw)
    if viscosity_change:
        u = UDFManager(path)
        u.put("ON", f"{VC}.viscosity_change")
        u.put(3.0, f"{VC}.ON.ETA_A")
        u.put(1.0, f"{VC}.ON.ETA_B")
        u.write(path)
    return path


def field_differences(a, b):
    """max |a - b| over the datasets of the HDF5 field files of two run directories (the
    same files in both)."""
    import h5py
    fa = sorted(os.path.basename(f) for f in glob.glob(os.path.join(a, "*.h5")))
    fb = sorted(os.path.basename(f) for f in glob.glob(os.path.join(b, "*.h5")))
    assert fa == fb and fa
    worst = 0.0
    for name in fa:
        with h5py.File(os.path.join(a, name)) as x, h5py.File(os.path.join(b, name)) as y:
            seen = []
            x.visititems(lambda n, o: seen.append(n) if hasattr(o, "shape") else None)
            assert seen
            for n in seen:
                assert x[n].shape == y[n].shape, (name, n)
                if x[n].size:
                    va, vb = np.asarray(x[n], dtype=float), np.asarray(y[n], dtype=float)
                    worst = max(worst, float(np.abs(va - vb).max()))
    return worst


CASES = [(NS, "explicit_scheme", "explicit_scheme", False),
         (NS, "implicit_scheme", "explicit_scheme", False),
         (NSCH, "explicit_scheme", "explicit_scheme", False),
         (NSCH, "implicit_scheme", "implicit_scheme", True)]


@pytest.mark.parametrize("eq,ns,ch,vc", CASES,
                         ids=[f"{e}-NS_{n[:8]}-CH_{c[:8]}{'-eta' if v else ''}"
                              for e, n, c, v in CASES])
def test_distributed_fdm_runs_agree_with_the_serial_run(tmp_path, eq, ns, ch, vc):
    """1, 2 (slab) and 4 (2 x 2 pencils) ranks against the serial run after 50 steps with
    4 particles: restart data (u, u_old, psi, psi_old, the particle table, R_raw), the
    records, the HDF5 field files (velocity, particles, order parameter, flux).  The last
    case has viscosity_change ON (the variable-viscosity implicit operator)."""
    ser = fdm_input(tmp_path / "serial", eq, ns, ch, vc)
    assert cli(tmp_path / "serial", ser) == 0
    assert saved_data(str(tmp_path / "serial" / "restart.udf"))["jikan"][0] == 50
    for n, grid in ((1, ()), (2, ()), (4, ("-X2", "-Y2"))):
        d = tmp_path / f"p{n}"
        fdm_input(d, eq, ns, ch, vc)
        mpirun(d, n, "input.udf", *grid)
        diff = differences(str(tmp_path / "serial"), str(d))
        diff["h5"] = field_differences(str(tmp_path / "serial"), str(d))
        print(f"{eq} NS {ns} CH {ch}{' eta(psi)' if vc else ''}, {n} rank(s): "
              f"max |distributed - serial| {diff}")
        if n == 1 and ns == ch == "explicit_scheme":
            assert max(diff.values()) == 0.0, diff      # the same stencils: the same bits
        else:
            assert max(diff.values()) < 1e-11, diff
        if n > 1:
            assert diff["Particles"] > 0 or diff["U"] > 0      # really distributed
    if eq == NSCH and ns == "implicit_scheme":
        # the same input, seed and process grid: the same bits (reductions in a fixed order)
        d = tmp_path / "p4_again"
        fdm_input(d, eq, ns, ch, vc)
        mpirun(d, 4, "input.udf", "-X2", "-Y2")
        again = differences(str(tmp_path / "p4"), str(d))
        assert max(again.values()) == 0.0, again


def _continue(d, n, snaps, *grid):
    from builders import continue_input
    continue_input(str(d), snaps)
    if n:
        mpirun(d, n, "cont.udf", *grid)
    else:
        assert cli(d, "cont.udf") == 0


@pytest.mark.parametrize("eq,ns,ch", [(NSCH, "implicit_scheme", "implicit_scheme"),
                                      (NSCH, "explicit_scheme", "explicit_scheme"),
                                      ("Shear_NS_LE_CH_FDM", "explicit_scheme",
                                       "implicit_scheme")])
def test_fdm_restarts_interchange_between_distributed_and_serial_runs(tmp_path, eq, ns, ch):
    """A restart written by a 2-rank run continues serially (2 x 1 ranks), a serial one on
    2 ranks (1 x 2: y split); both end where a serial run of the whole length does (to
    round-off).  The Lees-Edwards case (shear rate 0.5) re-maps its frame once, in the
    second half of the run."""
    kw = dict(particles=3, gts=5)

    def make(d, nsnap):
        if eq == NSCH:
            return fdm_input(d, eq, ns, ch, nsnap=nsnap, **kw)
        return le_input(d, eq, ns, 0.5, ch, nsnap=nsnap, **kw)
    one = make(tmp_path / "one", 4)
    assert cli(tmp_path / "one", one) == 0
    d = tmp_path / "dist_then_serial"
    make(d, 2)
    mpirun(d, 2, "input.udf")
    _continue(d, 0, 4)
    e = tmp_path / "serial_then_dist"
    inp = make(e, 2)
    assert cli(e, inp) == 0
    _continue(e, 2, 4, "-X1", "-Y2")
    if eq != NSCH:                  # the re-mapping falls into the continued half
        from kapsel.io.restart import state_path
        for path, remaps in ((tmp_path / "one" / "restart.udf", 1), (d / "cont.udf", 0)):
            with np.load(state_path(str(path))) as z:
                assert int(z["remaps"]) == remaps, path
    for x in (d, e):
        assert saved_data(str(x / "restart.udf"))["jikan"][0] == 20
        diff = differences(str(tmp_path / "one"), str(x))
        print(f"{x.name}: max |continued - serial| {diff}")
        assert max(diff.values()) < 1e-11, (x.name, diff)


LE, LECH = "Shear_Navier_Stokes_Lees_Edwards_FDM", "Shear_NS_LE_CH_FDM"


def le_input(d, eq, ns, rate, ch="explicit_scheme", viscosity_change=False, **kw):
    """The sample as a Lees-Edwards FDM type with DC shear ``rate`` and thermal noise."""
    kw = {"particles": 4, "gts": 10, "nsnap": 5, **kw}
    path = make_input(d, "Navier_Stokes", ns=ns, ch=ch, **kw)
    u = UDFManager(path)
    u.put(eq, "constitutive_eq.type")
    base = f"constitutive_eq.{eq}"
    u.put("DC", f"{base}.External_field.type")
    u.put(rate, f"{base}.External_field.DC.Shear_rate")
    u.put(0.5, f"{base}.kBT")
    u.put(ns, f"{base}.NS_solver.type")
    if eq == LECH:
        u.put(ch, f"{base}.CH_solver.type")
    if viscosity_change:
        v = f"{base}.NS_solver.implicit_scheme"
        u.put("ON", f"{v}.viscosity_change")
        u.put(3.0, f"{v}.ON.ETA_A")
        u.put(1.0, f"{v}.ON.ETA_B")
    u.write(path)
    return path


def _le_table(d):
    """The original's Lees-Edwards stress table (stdout of the run), one row per step."""
    return np.loadtxt(os.path.join(d, "table.txt"), comments="#")


LE_CASES = [pytest.param(LE, "explicit_scheme", "explicit_scheme", False,
                         marks=pytest.mark.slow),
            (LE, "implicit_scheme", "explicit_scheme", False),
            pytest.param(LECH, "explicit_scheme", "explicit_scheme", False,
                         marks=pytest.mark.slow),
            (LECH, "implicit_scheme", "implicit_scheme", True)]


@pytest.mark.parametrize("eq,ns,ch,vc", LE_CASES)
def test_lees_edwards_fdm_distributed(tmp_path, eq, ns, ch, vc):
    """The Lees-Edwards FDM types on 2 (slab) and 4 (2 x 2) ranks against the serial run:
    50 steps, 4 particles, thermal noise, shear rate 0.25 (the frame re-maps once: the row
    shift along the split x on the gathered rows, psi and psi_old shifted alike); the
    restart data, the records, the HDF5 field files (rectangular frame) and the stress
    table on stdout.  The Cahn-Hilliard case with both implicit schemes and
    viscosity_change (the oblique variable-viscosity term on a block widened by two
    layers).  10-20 s each on the 2-core machine (35 s busy); the explicit cases (the same halo code
    as the unsheared explicit types plus the metric terms the implicit operator uses too)
    are marked slow."""
    import subprocess
    from builders import MPIEXEC as mpiexec
    ser = le_input(tmp_path / "serial", eq, ns, 0.25, ch, vc)
    r = subprocess.run([sys.executable, "-m", "kapsel.cli", f"-I{ser}", "-Ooutput.udf",
                        "-Ddefine.udf", "-Rrestart.udf", "--seed", "11", "--quiet"],
                       cwd=tmp_path / "serial", capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    (tmp_path / "serial" / "table.txt").write_text(r.stdout)
    from kapsel.io.restart import state_path
    with np.load(state_path(str(tmp_path / "serial" / "restart.udf"))) as z:
        assert int(z["remaps"]) == 1
    for n, grid in ((2, ()), (4, ("-X2", "-Y2"))):
        d = tmp_path / f"p{n}"
        le_input(d, eq, ns, 0.25, ch, vc)
        r = subprocess.run([mpiexec, "-n", str(n), sys.executable, "-m", "kapsel.cli",
                            "-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                            "--seed", "11", "--quiet", *grid],
                           cwd=d, capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr[-2000:]
        (d / "table.txt").write_text(r.stdout)
        diff = differences(str(tmp_path / "serial"), str(d))
        diff["h5"] = field_differences(str(tmp_path / "serial"), str(d))
        ta, tb = _le_table(str(tmp_path / "serial")), _le_table(str(d))
        assert ta.shape == tb.shape and ta.shape[0] == 51
        diff["table"] = float(np.abs(ta - tb).max())
        print(f"{eq} NS {ns} CH {ch}{' eta(psi)' if vc else ''}, {n} ranks: "
              f"max |distributed - serial| {diff}")
        assert max(diff.values()) < 1e-11, diff
        assert diff["Particles"] > 0 or diff["U"] > 0


def test_a_type_that_is_not_distributed_is_refused_by_name(tmp_path):
    """Electrolyte (the one type left) is refused with more than one rank."""
    from builders import sample_el_input
    d = tmp_path / "el"
    sample_el_input(d)
    r = mpirun(d, 2, "input.udf", check=False)
    assert r.returncode == 2, r.stderr[-2000:]
    assert "Electrolyte does not run distributed" in r.stderr
    assert r.stderr.count("does not run distributed") == 1          # rank 0 speaks
    assert not (d / "output.udf").exists() and not (d / "restart.udf").exists()


def test_oblique_viscosity_change_refuses_blocks_of_one_point(tmp_path):
    """The oblique variable-viscosity term reaches 2 points: 4^3 on 4 slabs (blocks of one
    x plane) is refused with a message naming the process grid, exit 2, nothing written."""
    d = tmp_path / "thin"
    le_input(d, LECH, "implicit_scheme", 0.25, "implicit_scheme", True, particles=0, npx=2)
    r = mpirun(d, 4, "input.udf", "-X4", "-Y1", check=False)
    assert r.returncode == 2, r.stderr[-2000:]
    assert "viscosity_change in the oblique frame needs blocks of at least 2" in r.stderr
    assert not (d / "output.udf").exists() and not (d / "restart.udf").exists()


def _parallel_hdf5():
    from kapsel.models.common import parallel_hdf5
    return parallel_hdf5()


def _h5_files(d):
    """{file: {dataset: (dtype, shape, values)}, and the file's attributes} of a run's
    per-snapshot HDF5 files."""
    import h5py
    out = {}
    for path in sorted(glob.glob(os.path.join(d, "*.h5"))):
        with h5py.File(path) as f:
            sets = {}
            f.visititems(lambda n, o: sets.__setitem__(n, (o.dtype.str, o.shape, o[()]))
                         if hasattr(o, "shape") else None)
            out[os.path.basename(path)] = (sets, {k: f.attrs[k] for k in f.attrs})
    return out


@pytest.mark.skipif(not _parallel_hdf5(), reason="h5py is built without MPI (PyPI's wheels "
                    "are): the distributed runs gather the fields to rank 0, tested above")
@pytest.mark.parametrize("eq", [NSCH, LECH])
def test_parallel_hdf5_writes_the_files_of_a_plain_run(tmp_path, eq):
    """With an h5py built with MPI (parallel HDF5) a distributed run writes its
    per-snapshot field files with every rank writing its block (the rectangular-frame
    fields of a Lees-Edwards type, computed on rank 0 from gathered fields, by rank 0
    alone): on 2 and 2 x 2 ranks the same files, datasets, dtypes, shapes and attributes
    as the serial run's, values to round-off.  Runs where h5py has MPI (built against the
    MPI of mpi4py, e.g. HDF5_MPI=ON pip install --no-binary=h5py h5py); 20 s."""
    def make(d):
        if eq == NSCH:
            return fdm_input(d, NSCH, "implicit_scheme", "implicit_scheme")
        return le_input(d, LECH, "implicit_scheme", 0.25, ch="implicit_scheme")
    assert cli(tmp_path / "serial", make(tmp_path / "serial")) == 0
    want = _h5_files(str(tmp_path / "serial"))
    assert want
    for n, grid in ((2, ()), (4, ("-X2", "-Y2"))):
        d = tmp_path / f"p{n}"
        make(d)
        mpirun(d, n, "input.udf", *grid)
        got = _h5_files(str(d))
        assert sorted(got) == sorted(want)
        worst = 0.0
        for name, (sets, attrs) in want.items():
            gsets, gattrs = got[name]
            assert sorted(gsets) == sorted(sets), name
            assert gattrs.keys() == attrs.keys(), name
            for k in attrs:
                assert np.asarray(gattrs[k]).dtype == np.asarray(attrs[k]).dtype, (name, k)
                assert np.allclose(gattrs[k], attrs[k], rtol=0, atol=1e-12), (name, k)
            for k, (dt, shape, v) in sets.items():
                assert gsets[k][:2] == (dt, shape), (name, k)
                worst = max(worst, float(np.max(np.abs(np.asarray(gsets[k][2], float)
                                                       - np.asarray(v, float)), initial=0)))
        print(f"{eq}, parallel HDF5 on {n} ranks: max |distributed - serial| {worst:.2g}")
        assert worst < 1e-11
