"""Issue 26: kills, full disks and hostile files, each case of the audit as a test (the
kill / ENOSPC sweeps at exact system calls are in test_kill_points.py)."""
import errno
import os
import resource
import subprocess
import sys

import numpy as np
import pytest

from kapsel.cli import main
from kapsel.io import journal
from kapsel.io.records import RotationalEnergyLog, ShearLog
from udf import UDFManager

from builders import cli, make_input, one_line


KAPSEL = [sys.executable, "-c", "import sys; from kapsel.cli import main; sys.exit(main())"]


def run(d, *args, timeout=300, **kw):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    return subprocess.run(KAPSEL + list(args), cwd=d, capture_output=True, text=True,
                          env=env, timeout=timeout, **kw)


def main_in(d, capsys, monkeypatch, *args):
    """kapsel-py ``args`` run in-process in directory ``d``: (exit code, stderr)."""
    monkeypatch.chdir(d)
    code = main(list(args))
    return code, capsys.readouterr().err


def small(tmp_path, name="run", eq="Navier_Stokes_FDM", **kw):
    d = tmp_path / name
    kw.setdefault("kBT", 0.0)
    kw.setdefault("npx", 3)
    make_input(d, eq, ns="explicit_scheme", **kw)
    u = UDFManager(str(d / "input.udf"))
    u.put(2.0, "A")
    u.put(1.0, "A_XI")
    u.write(str(d / "input.udf"))
    return d


def put(d, src, dst, **items):
    u = UDFManager(str(d / src))
    for path, value in items.items():
        u.put(value, path.replace("__", "."))
    u.write(str(d / dst))


# ------------------------------------------------- 1. EXTENDED trajectory and its journal
def test_1_killed_extended_write_is_put_back_to_its_last_frame(tmp_path):
    """A trajectory torn mid-frame (what a kill leaves: pages of the file changed, the
    journal holding their old bytes) is put back byte for byte by the next run's lock;
    the exhaustive version (every system call of a snapshot) is test_kill_points."""
    import h5py
    path = str(tmp_path / "data.h5")
    jf = journal.JournaledFile(path, create=True)
    with h5py.File(jf, "w") as f:
        f.create_dataset("a", data=np.arange(1000.0))
        f.flush()
        jf.commit()
        good = open(path, "rb").read()
        f.create_group("frame_1").create_dataset("b", data=np.ones(5000))
        f.flush()                     # written, not committed: as if killed here
        os.write(jf.fd, b"")          # (the next line is what a kill does: nothing more)
        assert os.path.exists(journal.journal_path(path))
        torn = open(path, "rb").read()
        assert torn != good
        jf.dead = True                # the process is gone: no close reaches the file
    assert journal.recover_all(str(tmp_path)) == ["data.h5"]
    assert open(path, "rb").read() == good
    assert not os.path.exists(journal.journal_path(path))
    with h5py.File(path, "r") as f:
        assert list(f) == ["a"]


# ------------------------------------------------- 2. the two renames of the restart write
def test_2_kill_between_the_restart_renames_continues_from_the_new_state(tmp_path):
    """The state file is replaced first; killed before restart.udf follows, the old
    restart.udf and the new state file continue the run from the new state (not from step
    0), bit-identical; both renames are preceded by fsync (checked on the system calls in
    test_kill_points.test_every_rename_is_preceded_by_fsync)."""
    from kapsel.io import restart
    from builders import saved_data
    whole = small(tmp_path, "whole", gts=2, nsnap=3, kBT=0.5)
    assert cli(whole, "input.udf") == 0
    d = small(tmp_path, "killed", gts=2, nsnap=3, kBT=0.5)
    real = restart.put_in_place
    calls = []

    class Killed(BaseException):
        """Stands for SIGKILL: nothing of the run's own error handling runs."""

    def killed(tmp, path):
        real(tmp, path)
        calls.append(path)
        # renames: state + text at step 0, checkpoints at 2, 4, 6, then the final state
        if len(calls) == 6:
            assert path.endswith(".state.npz")
            raise Killed
    restart.put_in_place = killed
    try:
        with pytest.raises(Killed):
            cli(d, "input.udf")
    finally:
        restart.put_in_place = real
    doc = UDFManager(str(d / "restart.udf"))
    assert doc.get("resume.CONTINUE_FDM.Saved_Data.jikan")[0] == -1    # still step 0's text
    assert cli(d, "restart.udf") == 0           # says: nothing to do, and completes the text
    assert (d / "restart.udf").read_bytes() == (whole / "restart.udf").read_bytes()
    a, b = saved_data(str(whole / "restart.udf")), saved_data(str(d / "restart.udf"))
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


# ------------------------------------------------- 3. a full disk in an HDF5 field write
def test_3_full_disk_in_an_hdf5_write_is_one_line(tmp_path, monkeypatch, capsys):
    from kapsel.io import h5file
    d = small(tmp_path, gts=2, nsnap=3)
    real = h5file._pwrite_all
    count = [0]

    def full(fd, data, off):
        count[0] += 1
        if count[0] == 12:               # inside the second snapshot's files
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(fd, data, off)
    monkeypatch.setattr(h5file, "_pwrite_all", full)
    monkeypatch.chdir(d)
    assert main(["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--seed",
                 "1", "--quiet"]) == 1
    line = one_line(capsys.readouterr().err)
    assert "the disk is full" in line and ".h5 at step" in line, line
    assert not [f for f in os.listdir(d) if "kapsel-tmp" in f]


def _small_tmpfs(where, size):
    os.makedirs(where)
    if os.geteuid() != 0:
        return False
    return subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs",
                           str(where)], capture_output=True).returncode == 0


@pytest.mark.slow
@pytest.mark.parametrize("size", ["300k", "1100k"])
def test_3_real_full_tmpfs_with_the_plain_sample(tmp_path, size):
    """The plain sample (Navier_Stokes_Cahn_Hilliard_FDM, 32^3, 8 particles) on a tiny
    tmpfs, a snapshot every 2 steps: the disk fills in the first or second snapshot (root
    only; about 30 s each on the busy 2-core machine, hence slow; the in-process ENOSPC test
    above is the fast one)."""
    from builders import sample_input
    disk = tmp_path / "disk"
    if not _small_tmpfs(disk, size):
        pytest.skip("cannot mount a tmpfs here (root only)")
    try:
        u = sample_input(str(disk), "Navier_Stokes_Cahn_Hilliard_FDM", 5)
        u.put(2, "output.GTS")
        u.put(40, "output.Num_snap")
        u.write(str(disk / "input.udf"))
        r = run(disk, "-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                "--seed", "1", "--quiet")
        assert r.returncode == 1, r.stderr
        assert "the disk is full" in one_line(r.stderr)
        assert r.returncode != -11
    finally:
        subprocess.run(["umount", str(disk)])


# ------------------------------------------------- 4. one AVS Out_dir, two runs
def test_4_two_runs_with_one_avs_out_dir(tmp_path):
    shared = tmp_path / "fields"
    dirs = []
    for name in ("a", "b"):
        d = small(tmp_path, name, eq="Navier_Stokes", gts=2, nsnap=200)
        put(d, "input.udf", "input.udf", output__AVS="ON", output__ON__FileType="EXTENDED",
            output__ON__Out_dir=str(shared),
            output__ON__EXTENDED__Print_field__Crop="NO")
        dirs.append(d)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    first = subprocess.Popen(KAPSEL + ["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf",
                                       "-Rrestart.udf", "--quiet", "--seed", "1"],
                             cwd=dirs[0], env=env, stderr=subprocess.PIPE, text=True)
    try:
        for _ in range(600):
            if (dirs[0] / "output.udf").exists():
                break
            first.poll()
            assert first.returncode is None, first.stderr.read()
            import time
            time.sleep(0.1)
        r = run(dirs[1], "-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                "--overwrite", "--quiet")
        assert r.returncode == 2
        line = one_line(r.stderr)
        assert "another kapsel-py run is writing into" in line and str(shared) in line
    finally:
        first.kill()
        first.wait()


def test_4_the_legacy_avs_subdirectory_is_under_the_lock(tmp_path):
    """Legacy AVS writes <Out_dir>/avs/*.dat: a second run whose -O and -R are in that
    directory is refused while the first holds its locks (re-audit 2026-12-04)."""
    from kapsel import config
    from kapsel.startup import lock_output_dirs
    d = small(tmp_path, "a", eq="Navier_Stokes")
    shared = tmp_path / "fields"
    put(d, "input.udf", "input.udf", output__AVS="ON", output__ON__FileType="BINARY",
        output__ON__Out_dir=str(shared))
    cfg = config.load(str(d / "input.udf"))

    class Args:
        output, restart, quiet = str(d / "output.udf"), str(d / "restart.udf"), True
    held, problem = lock_output_dirs(Args, cfg)
    assert problem is None
    try:
        class Other:
            output = str(shared / "avs" / "output.udf")
            restart = str(shared / "avs" / "restart.udf")
            quiet = True
        again, problem = lock_output_dirs(Other, None)
        assert again is None
        assert "another kapsel-py run is writing into" in problem and "avs" in problem
    finally:
        for h in held:
            h.close()


# ------------------------------------------------- 5. \include of a FIFO or a device
@pytest.mark.parametrize("target", ["fifo", "/dev/zero"])
def test_5_include_of_a_fifo_or_device_is_refused(tmp_path, target):
    d = small(tmp_path)
    if target == "fifo":
        os.mkfifo(d / "fifo")
    text = (d / "input.udf").read_text()
    (d / "bad.udf").write_text(f'\\include{{"{target}"}}\n' + text)
    r = run(d, "-Ibad.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--check",
            timeout=60)
    assert r.returncode == 2
    line = one_line(r.stderr)
    assert "not a regular file" in line and ("FIFO" in line or "character device" in line)


def test_5_fifo_as_input_define_or_state_file(tmp_path):
    d = small(tmp_path)
    os.mkfifo(d / "fifo.udf")
    r = run(d, "-Ififo.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", timeout=60)
    assert r.returncode == 2 and "is a FIFO, not a regular file" in one_line(r.stderr)
    r = run(d, "-Iinput.udf", "-Ooutput.udf", "-Dfifo.udf", "-Rrestart.udf", timeout=60)
    assert r.returncode == 2 and "is a FIFO, not a regular file" in one_line(r.stderr)
    from kapsel.io.restart import read_restart
    assert cli(d, "input.udf") == 0
    os.unlink(d / "restart.udf.state.npz")
    os.mkfifo(d / "restart.udf.state.npz")
    doc = UDFManager(str(d / "restart.udf"))
    saved = read_restart(doc, str(d / "restart.udf"), "CONTINUE_FDM")   # does not block
    assert saved.exact is None and "not a regular file" in saved.state_damaged


def test_5_sigterm_during_start_up_is_left_to_the_kernel():
    """SIGTERM in start-up is not deferred to a Python handler (which a blocked or spinning
    C call never lets run): its default action ends the process at once; start-up has
    written nothing.  SIGINT is noted and acted on between the stages, as before."""
    import signal
    from kapsel.cli import StartUpSignals
    with StartUpSignals() as s:
        assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
        assert signal.getsignal(signal.SIGINT) == s._note
    before = signal.getsignal(signal.SIGTERM)
    with StartUpSignals():
        pass
    assert signal.getsignal(signal.SIGTERM) == before


# ------------------------------------------------- 6. out of memory
@pytest.mark.parametrize("kib", [150_000, 200_000, 280_000])
def test_6_low_address_space_limit_is_one_line(tmp_path, kib):
    d = small(tmp_path)

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (kib * 1024, resource.RLIM_INFINITY))
    r = run(d, "-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--quiet",
            preexec_fn=limit, timeout=120)
    assert r.returncode == 1, r.stderr
    assert "ulimit -v" in one_line(r.stderr)


def test_6_memory_error_at_set_up_and_at_the_last_restart(tmp_path, monkeypatch, capsys):
    from kapsel.io import restart
    import kapsel.typespec as sim
    d = small(tmp_path, gts=2, nsnap=2)
    monkeypatch.chdir(d)
    args = ["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--quiet",
            "--seed", "1"]

    def no_memory(*a, **k):
        raise MemoryError
    monkeypatch.setitem(sim.SOLVERS, "Navier_Stokes_FDM", no_memory)
    assert main(args) == 1
    assert "out of memory while setting up" in one_line(capsys.readouterr().err)
    monkeypatch.undo()
    monkeypatch.chdir(d)
    real, n = restart.write_restart, []

    def last_fails(*a, **k):
        n.append(1)
        if a[4] > 4:                  # the final restart (after step 5)
            raise MemoryError
        return real(*a, **k)
    monkeypatch.setattr(restart, "write_restart", last_fails)
    assert main(args + ["--overwrite"]) == 1
    line = one_line(capsys.readouterr().err)
    assert "out of memory at step 5" in line and "holds the last good state (step 4)" in line


# ------------------------------------------------- 7. torn .dat rows
@pytest.mark.parametrize("log", [ShearLog, RotationalEnergyLog])
def test_7_torn_table_row_is_dropped_not_merged(tmp_path, log, capsys):
    path = str(tmp_path / "table.dat")
    make = (lambda append: log(path, append=append, until_step=4)) if log is ShearLog \
        else (lambda append: log(path, 2, append=append, until_step=4))
    t = make(False)
    rows = ({"Shear_strain": 0.1, "Shear_rate": 0.2, "Shear_stress": 0.3}
            if log is ShearLog else [0.5, 0.25])
    for step in (0, 2, 4):
        t.write(step, step * 0.1, rows)
    with open(path, "a") as fh:
        fh.write("6 0.6 0.1")        # killed in the middle of the row of step 6
    t = make(True)
    assert "its last line was incomplete" in capsys.readouterr().err
    t.write(6, 0.6, rows)
    lines = open(path).read().splitlines()
    assert [int(ln.split()[0]) for ln in lines[1:]] == [0, 2, 4, 6]
    assert len({len(ln.split()) for ln in lines[1:]}) == 1


def test_7_failed_row_append_is_cut_back(tmp_path, monkeypatch):
    path = str(tmp_path / "table.dat")
    t = ShearLog(path)
    t.write(0, 0.0, {"Shear_strain": 0, "Shear_rate": 1, "Shear_stress": 2})
    before = open(path, "rb").read()
    real = os.write

    def half(fd, data):
        real(fd, bytes(data[:len(data) // 2]))
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(os, "write", half)
    with pytest.raises(OSError, match="No space left"):
        t.write(2, 0.2, {"Shear_strain": 0, "Shear_rate": 1, "Shear_stress": 2})
    monkeypatch.undo()
    assert open(path, "rb").read() == before


# ------------------------------------------------- 8, 9. bad values
@pytest.mark.parametrize("value,says", [(1e308, "between 1e-30 and 1e+30"),
                                        (1e23, "does not fit in the box")])
@pytest.mark.parametrize("check", [True, False])
def test_8_huge_radius_is_refused(tmp_path, value, says, check, capsys, monkeypatch):
    d = small(tmp_path)
    put(d, "input.udf", "bad.udf", A=value)
    code, err = main_in(d, capsys, monkeypatch, "-Ibad.udf", "-Ooutput.udf", "-Ddefine.udf",
                        "-Rrestart.udf", *(["--check"] if check else []))
    assert code == 2
    assert says in one_line(err)


@pytest.mark.parametrize("path,value", [
    ("A", 1e308),                       # with user_specify placement: overflowed in the cells
    ("constitutive_eq.Electrolyte.kBT", 1e308),
    ("constitutive_eq.Electrolyte.Add_salt.salt.Debye_length", 1e308),
    ("constitutive_eq.Electrolyte.Add_salt.salt.Debye_length", 1e-308),
    ("constitutive_eq.Electrolyte.Add_salt.salt.Onsager_coeff_positive_ion", 1e308),
    ("constitutive_eq.Electrolyte.Dielectric_cst", 1e-308),
    ("constitutive_eq.Electrolyte.RHO", 1e-308),
    ("constitutive_eq.Electrolyte.Electric_field.ON.DC.Ex", 1e308),
    ("object_type.spherical_particle.Particle_spec[0].MASS_RATIO", 5e-324)])
@pytest.mark.parametrize("check", [True, False])
def test_8_a_parameter_beyond_any_physical_size_is_one_line(tmp_path, path, value, check,
                                                            capsys, monkeypatch):
    """The class of the audit's extreme values (re-audit 2026-12-04: tracebacks of
    OverflowError, ZeroDivisionError, ValueError in the set-up): every number the input
    check reads as a parameter is 0 or between 1e-30 and 1e30 in size, refused in one line
    naming it, before anything is written (Electrolyte with user-placed particles: the
    types and paths of the audit)."""
    from builders import electrolyte_input as el_input
    d = tmp_path / "el"
    el_input(d, npx=3, A=2.0)
    u = UDFManager(str(d / "input.udf"))
    u.put(1.0, "A_XI")
    u.put(value, path)
    u.write(str(d / "bad.udf"))
    code, err = main_in(d, capsys, monkeypatch, "-Ibad.udf", "-Ooutput.udf", "-Ddefine.udf",
                        "-Rrestart.udf", *(["--check"] if check else []))
    assert code == 2, err
    line = one_line(err)
    assert path.rsplit(".", 1)[-1] in line and "between 1e-30 and 1e+30" in line
    assert not (d / "output.udf").exists()


@pytest.mark.parametrize("check", [True, False])
def test_8_electrolyte_with_kbt_zero_is_refused(tmp_path, check, capsys, monkeypatch):
    from builders import electrolyte_input as el_input
    d = tmp_path / "el"
    el_input(d, npx=3, A=2.0)
    put(d, "input.udf", "bad.udf", constitutive_eq__Electrolyte__kBT=0.0)
    code, err = main_in(d, capsys, monkeypatch, "-Ibad.udf", "-Ooutput.udf", "-Ddefine.udf",
                        "-Rrestart.udf", *(["--check"] if check else []))
    assert code == 2
    line = one_line(err)
    assert "kBT" in line and "must be positive for Electrolyte" in line


def test_9_infinite_particle_mass_is_refused(tmp_path, capsys, monkeypatch):
    d = small(tmp_path)
    u = UDFManager(str(d / "input.udf"))
    u.put(1e308, "object_type.spherical_particle.Particle_spec[0].MASS_RATIO")
    u.write(str(d / "bad.udf"))
    code, err = main_in(d, capsys, monkeypatch, "-Ibad.udf", "-Ooutput.udf", "-Ddefine.udf",
                        "-Rrestart.udf")
    assert code == 2
    assert "MASS_RATIO" in one_line(err) and "between 1e-30 and 1e+30" in err
    assert not (d / "output.udf").exists()


# ------------------------------------------------- 10. analyze
def test_10_analyze_sq_skips_a_torn_snapshot_and_refuses_a_directory_table(tmp_path, capsys):
    import h5py
    d = tmp_path / "sq"
    d.mkdir()
    for n in (0, 1):
        with h5py.File(d / f"orderparam_{n}.h5", "w") as f:
            f["PSI"] = np.random.default_rng(n).standard_normal((8, 8, 8))
    data = (d / "orderparam_1.h5").read_bytes()
    (d / "orderparam_1.h5").write_bytes(data[:len(data) // 3])       # torn
    assert main(["analyze", "sq", str(d), "--plot", str(tmp_path / "sq.png")]) == 0
    err = capsys.readouterr().err
    assert "orderparam_1.h5 is skipped" in err
    (tmp_path / "tab").mkdir()
    assert main(["analyze", "sq", str(d), "--table", str(tmp_path / "tab")]) == 2
    assert "is a directory" in one_line(capsys.readouterr().err)


def test_10_analyze_cna_on_a_small_box(tmp_path, capsys):
    xyz = tmp_path / "small.xyz"
    xyz.write_text('4\nLattice="3 0 0 0 3 0 0 0 3"\nA 0 0 0\nA 1.5 0 0\nA 0 1.5 0\n'
                   'A 0 0 1.5\n')
    assert main(["analyze", "cna", str(xyz)]) == 2
    assert "not below half the periodic box" in one_line(capsys.readouterr().err)


def test_10_analyze_bad_dx_fields_and_frames_are_one_line(tmp_path, capsys):
    """The re-audit's variations (2026-12-04): `sq` with --dx 0, a snapshot whose dataset
    is not a 3-D field (skipped); `cna` with a coordinate far outside its periodic box
    (wrapped), a vanishing box, a non-positive --cutoff."""
    import h5py
    d = tmp_path / "sq"
    d.mkdir()
    with h5py.File(d / "orderparam_0.h5", "w") as f:
        f["PSI"] = np.random.default_rng(0).standard_normal((8, 8, 8))
    with h5py.File(d / "orderparam_1.h5", "w") as f:
        f["PSI"] = np.ones(5)
    assert main(["analyze", "sq", str(d), "--dx", "0"]) == 2
    assert "--dx" in one_line(capsys.readouterr().err)
    assert main(["analyze", "sq", str(d), "--plot", str(tmp_path / "sq.png")]) == 0
    err = capsys.readouterr().err
    assert "orderparam_1.h5 is skipped" in err and "not a 3-D numeric field" in err
    far = tmp_path / "far.xyz"
    far.write_text('2\nLattice="3 0 0 0 3 0 0 0 3"\nA 0 0 0\nA 1e308 0 0\n')
    assert main(["analyze", "cna", str(far)]) == 0
    assert "Traceback" not in capsys.readouterr().err
    tiny = tmp_path / "tiny.xyz"
    tiny.write_text('3\nLattice="1e-300 0 0 0 1e-300 0 0 0 1e-300"\nA 0 0 0\nA 0 0 0\n'
                    'A 0 0 0\n')
    assert main(["analyze", "cna", str(tiny)]) == 2
    assert "not a positive number" in one_line(capsys.readouterr().err)
    assert main(["analyze", "cna", str(far), "--cutoff", "-1"]) == 2
    assert "not a positive number" in one_line(capsys.readouterr().err)


# ------------------------------------------------- 11. temporaries and the seed
def dead_pid() -> int:
    """The pid of a process that has ended (the writer of a killed write)."""
    p = subprocess.Popen(["true"])
    p.wait()
    return p.pid


def test_11_temporaries_of_killed_writes_are_removed(tmp_path, capsys, monkeypatch):
    """A continuation removes what killed writes left (their writer's pid no longer runs)
    and keeps the work in progress of a live writer (here: this test's parent process, as
    an `analyze` writing its table into the run's directory would be)."""
    d = small(tmp_path, gts=2, nsnap=2)
    assert cli(d, "input.udf") == 0
    pid = dead_pid()
    left = [d / f".restart.udf.state.npz.{pid}.0123abcd.kapsel-tmp",
            d / f".velocity_2.h5.{pid}.89abcdef.kapsel-tmp",
            d / f"restart.udf.state.npz.tmp{pid}", d / f".output.udf.{pid}.deadbeef.tmp"]
    for p in left:
        p.write_bytes(b"x" * 1000)
    (d / "notes.tmp").write_text("mine")          # not ours: kept
    live = d / f".sq.txt.{os.getppid()}.00112233.kapsel-tmp"
    live.write_text("in progress")
    put(d, "restart.udf", "restart.udf", output__Num_snap=3)
    monkeypatch.chdir(d)
    assert main(["-Irestart.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf"]) == 0
    assert "removed 4 temporary files" in capsys.readouterr().err
    assert not any(p.exists() for p in left) and (d / "notes.tmp").exists()
    assert live.read_text() == "in progress"


def test_11_analyze_removes_what_its_killed_writes_left(tmp_path, capsys):
    """`analyze sq` removes the temporaries a killed `analyze` left of the files it writes
    (its table and plot), and nothing else."""
    from kapsel.cli import main as kmain
    import h5py
    d = tmp_path / "run"
    d.mkdir()
    with h5py.File(d / "orderparam_0.h5", "w") as f:
        f["PSI"] = np.random.default_rng(0).standard_normal((8, 8, 8))
    pid = dead_pid()
    mine = [d / f".sq.txt.{pid}.0123abcd.kapsel-tmp", d / f".sq.png.{pid}.89abcdef.kapsel-tmp"]
    other = d / f".output.udf.{pid}.deadbeef.kapsel-tmp"      # a run's: under its lock
    for p in mine + [other]:
        p.write_bytes(b"x")
    assert kmain(["analyze", "sq", str(d), "--table", str(d / "sq.txt"),
                  "--plot", str(d / "sq.png")]) == 0
    assert not any(p.exists() for p in mine) and other.exists()
    assert (d / "sq.txt").is_file()


def test_11_continuation_without_seed_keeps_the_runs_seed(tmp_path, capsys, monkeypatch):
    from kapsel.io.records import RUN_MARK
    d = small(tmp_path, gts=2, nsnap=2, kBT=0.5)
    assert cli(d, "input.udf") == 0                  # --seed 11
    put(d, "restart.udf", "restart.udf", output__Num_snap=4)
    code, err = main_in(d, capsys, monkeypatch, "-Irestart.udf", "-Ooutput.udf",
                        "-Ddefine.udf", "-Rrestart.udf", "--quiet")
    assert code == 0, err
    first = (d / "output.udf").read_text().splitlines()[0]
    assert RUN_MARK in first and "random seed 11 " in first
    with np.load(d / "restart.udf.state.npz") as z:
        assert str(z["seed"]).strip('"') == "11"


@pytest.mark.parametrize("state", ["damaged", "missing"])
def test_11_continuation_without_a_usable_state_file_keeps_output_udfs_seed(
        tmp_path, state, capsys, monkeypatch):
    """A continuation whose restart has no usable state file (damaged, or a copy of
    restart.udf without it) and no --seed takes the seed and run id output.udf's first line
    names, so that line stays true of the run it appends to (re-audit 2026-12-04: a fresh
    seed was drawn and written into the new state file)."""
    from kapsel.io.records import run_line
    d = small(tmp_path, gts=2, nsnap=2, kBT=0.5)
    assert cli(d, "input.udf") == 0                  # --seed 11
    put(d, "restart.udf", "cont.udf", output__Num_snap=4)
    if state == "damaged":
        put(d, "restart.udf", "restart.udf", output__Num_snap=4)
        (d / "restart.udf.state.npz").write_bytes(b"garbage")
        src = "restart.udf"
    else:
        src = "cont.udf"
    named = run_line(str(d / "output.udf"))
    assert named is not None and named[1] == 11
    code, err = main_in(d, capsys, monkeypatch, f"-I{src}", "-Ooutput.udf",
                        "-Ddefine.udf", "-Rrestart.udf", "--quiet")
    assert code == 0, err
    assert run_line(str(d / "output.udf")) == named
    with np.load(d / "restart.udf.state.npz") as z:
        assert str(z["seed"]).strip('"') == "11"
        assert str(z["run_id"]).strip('"') == named[0]


def test_a_compiled_kernel_load_that_fails_leaves_the_numpy_passes(monkeypatch, capsys):
    """numba's code generator failing to load (out of memory under ulimit -v: an OSError
    from llvmlite) is one note and the numpy passes (the same numbers), not a write failure
    (re-audit 2026-12-04)."""
    import importlib
    from kapsel.mesh import compiled
    was = compiled._enabled
    compiled.disable()

    def fail(name, *a, **k):
        raise OSError("Could not find/load shared object file 'libllvmlite.so'")
    monkeypatch.setattr(importlib, "import_module", fail)
    monkeypatch.setenv("KAPSEL_PY_COMPILED", "auto")
    try:
        assert compiled.enable() is False
        assert compiled.spectral is None and compiled.stencils is None
        assert "the numpy passes" in one_line(capsys.readouterr().err)
    finally:
        monkeypatch.undo()
        if was:
            compiled.enable()


def test_a_fifo_in_place_of_a_snapshot_file_is_not_opened(tmp_path):
    """A continuation reads the times of the snapshot files on disk: a FIFO at such a path is
    treated as no file (it would block the open for ever), as the audit of 2026-12-02 found
    for velocity_1.h5 of an FDM continuation."""
    import threading
    from kapsel.io.fields import _stored_time
    fifo = tmp_path / "velocity_1.h5"
    os.mkfifo(fifo)
    got = []
    t = threading.Thread(target=lambda: got.append(_stored_time(str(fifo), 1.5)), daemon=True)
    t.start()
    t.join(10)
    assert not t.is_alive(), "the FIFO was opened"
    assert got == [1.5]


# ------------------------------------------------- 5. FIFOs and devices among the outputs
def _extended(d):
    put(d, "input.udf", "input.udf", output__AVS="ON", output__ON__Out_dir="avs",
        output__ON__Out_name="data", output__ON__FileType="EXTENDED",
        output__ON__EXTENDED__Print_field__Crop="NO")


@pytest.mark.parametrize("target", ["fifo", "/dev/zero"])
def test_5_fifo_or_device_in_place_of_an_output_is_never_replaced(tmp_path, target, capsys,
                                                                   monkeypatch):
    """The files a run replaces besides -O / -R (output.AVS's file, the .xmf series, the
    .dat tables) are refused with one line before anything is written when they are a FIFO
    or a device (a symbolic link to /dev/zero), by a continuation and by a new run with
    --overwrite, as -O and -R are; never read (a FIFO would block, /dev/zero never ends),
    never replaced."""
    d = small(tmp_path, gts=2, nsnap=2)
    _extended(d)
    assert cli(d, "input.udf") == 0
    put(d, "restart.udf", "cont.udf", output__Num_snap=3)
    before = (d / "output.udf").read_bytes()
    for rel in ("avs/data.h5", "velocity_field.xmf"):
        p = d / rel
        saved = p.read_bytes()
        p.unlink()
        os.mkfifo(p) if target == "fifo" else os.symlink(target, p)
        for args in (["-Icont.udf"], ["-Iinput.udf", "--overwrite"]):
            code, err = main_in(d, capsys, monkeypatch, *args, "-Ooutput.udf",
                                "-Ddefine.udf", "-Rrestart.udf")
            assert code == 2, err
            assert "not a regular file; it is never replaced" in one_line(err), err
            assert rel.split("/")[-1] in err
        assert (d / "output.udf").read_bytes() == before
        assert p.is_fifo() if target == "fifo" else p.is_symlink()
        p.unlink()
        p.write_bytes(saved)


def test_5_fifo_in_place_of_a_table_is_never_replaced(tmp_path, capsys, monkeypatch):
    from builders import shear_input as le_input
    d = tmp_path / "le"
    le_input(str(d), particles=1, gts=2, nsnap=2, npx=3)
    put(d, "input.udf", "input.udf", A=1.5, A_XI=1.0)
    assert cli(d, "input.udf") == 0
    put(d, "restart.udf", "cont.udf", output__Num_snap=3)
    (d / "shear_stress.dat").unlink()
    os.mkfifo(d / "shear_stress.dat")
    code, err = main_in(d, capsys, monkeypatch, "-Icont.udf", "-Ooutput.udf", "-Ddefine.udf",
                        "-Rrestart.udf")
    assert code == 2 and "shear_stress.dat: is a FIFO" in one_line(err), err


def test_5_readers_refuse_fifos(tmp_path):
    """Every reader of a file a run left (the journal, the trajectory, a table, output.udf's
    run id, a legacy AVS .fld) opens it through udf.files.open_regular: a FIFO is refused at
    once, never waited on."""
    import threading
    from kapsel.io import avs, records
    from kapsel.io.journal import JournaledFile, journal_path, recover
    from udf.files import NotRegularFile
    fifo = tmp_path / "data.h5"
    os.mkfifo(fifo)
    os.mkfifo(journal_path(str(tmp_path / "other.h5")))
    calls = [lambda: JournaledFile(str(fifo)), lambda: recover(str(tmp_path / "other.h5")),
             lambda: records.TableLog(str(fifo), ("a",), append=True),
             lambda: records.run_id(str(fifo)), lambda: avs._kept_blocks(str(fifo), 10)]
    got = []

    def attempt():
        for c in calls:
            try:
                got.append(c())
            except NotRegularFile:
                got.append("refused")
    t = threading.Thread(target=attempt, daemon=True)
    t.start()
    t.join(20)
    assert not t.is_alive(), f"a FIFO was opened and waited on after {got}"
    assert got == ["refused"] * 3 + [None, []]


def test_define_file_is_read_once_at_start_up(tmp_path):
    """The restart writes take define.udf's schema as read at start-up: the file removed
    (or unreadable: EIO, EACCES) during the run changes nothing, and the restart written
    is the one an undisturbed run writes.  (Before: every full restart write read the
    file again, and a read failure there ended in a UDFError traceback.)"""
    from builders import api_simulation, api_input
    runs = {}
    for name in ("kept", "removed"):
        d = tmp_path / name
        d.mkdir()
        api_input(str(d), "Navier_Stokes_FDM")
        sim = api_simulation(str(d), overrides={"output.Num_snap": 2})
        sim.run(2)
        if name == "removed":
            (d / "define.udf").rename(d / "define.away")
        sim.run()
        runs[name] = (d / "restart.udf").read_bytes()
    assert runs["kept"] == runs["removed"]


def test_a_library_that_cannot_be_read_is_one_line(tmp_path, capsys, monkeypatch):
    """A shared library or module the run loads later (numpy's random, h5py) that cannot
    be read (EACCES, EIO: found by injecting EACCES at every openat of a continuation) is
    one line and exit 1; any other ImportError stays a traceback (a broken install or a bug
    must show where)."""
    import kapsel.cli as kcli
    d = small(tmp_path)

    def fails(args, locks):
        raise ImportError("/x/_generator.so: cannot open shared object file: Permission denied")
    monkeypatch.setattr(kcli, "_main", fails)
    code, err = main_in(d, capsys, monkeypatch, "-Iinput.udf")
    assert code == 1 and "cannot load a library" in one_line(err)

    def other(args, locks):
        raise ImportError("No module named 'nothing'")
    monkeypatch.setattr(kcli, "_main", other)
    with pytest.raises(ImportError):
        main_in(d, capsys, monkeypatch, "-Iinput.udf")
