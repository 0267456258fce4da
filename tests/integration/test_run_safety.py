"""A run never loses or mixes what it wrote (issue 12, defects 1-10), each in the real
situation: a -D that differs from the input's schema, two processes at once, a torn
output.udf tail, another run's output.udf, damaged state files, a full disk, symlinks and
special files, out-of-range values, blow-ups, seeds, finished runs."""
import errno
import os
import shutil
import signal
import stat
import subprocess
import sys
import time

import numpy as np
import pytest

from kapsel.cli import main
from kapsel.io.restart import state_path
from udf import UDFManager

from builders import cli, make_input, TESTS


KAPSEL = [sys.executable, "-m", "kapsel.cli"]


def run(d, *args, timeout=300):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    return subprocess.run(KAPSEL + list(args), cwd=d, capture_output=True, text=True,
                          env=env, timeout=timeout)


def small(tmp_path, name="run", **kw):
    d = tmp_path / name
    kw.setdefault("kBT", 0.0)
    make_input(d, "Navier_Stokes_FDM", ns="explicit_scheme", **kw)
    return d


def other_define(d):
    """define.udf with one more member in mesh: the input was written with the other one."""
    text = (d / "define.udf").read_text()
    key = '   NPZ: int "number of mesh in z-direction = 2^NPZ"\n'
    assert key in text
    (d / "define2.udf").write_text(text.replace(key, key + "   extra: int\n"))


# ---------------------------------------------------------------- 1. -D mismatch
def test_define_that_differs_from_the_input_is_refused(tmp_path, capsys, monkeypatch):
    d = small(tmp_path)
    other_define(d)
    monkeypatch.chdir(d)
    assert main(["-Iinput.udf", "-Ooutput.udf", "-Ddefine2.udf", "-Rrestart.udf",
                 "--seed", "1", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "-Ddefine2.udf: defines mesh differently" in err
    assert not (d / "output.udf").exists() and not (d / "restart.udf").exists()
    # a continued run keeps its good checkpoint
    assert cli(d, "input.udf") == 0
    good = (d / "restart.udf").read_bytes()
    assert main(["-Irestart.udf", "-Ooutput.udf", "-Ddefine2.udf", "-Rrestart.udf",
                 "--seed", "1", "--quiet"]) == 2
    assert (d / "restart.udf").read_bytes() == good
    UDFManager(str(d / "restart.udf"))
    UDFManager(str(d / "output.udf"))
    # a define without a place for an item of the input
    text = (d / "define.udf").read_text()
    key = "Unit_Parameter:"
    assert key in text
    (d / "define3.udf").write_text(text.replace(key, "Unit_Parameter_elsewhere:"))
    assert main(["-Irestart.udf", "-Ooutput.udf", "-Ddefine3.udf", "-Rrestart.udf",
                 "--quiet"]) == 2
    assert "has no place for Unit_Parameter" in capsys.readouterr().err
    assert (d / "restart.udf").read_bytes() == good


# ---------------------------------------------------------------- 2. two runs at once
def test_two_runs_into_one_directory(tmp_path):
    d = small(tmp_path, gts=5, nsnap=100000)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    args = KAPSEL + ["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                     "--seed", "3", "--quiet"]
    first = subprocess.Popen(args, cwd=d, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.time() + 120
    while not (d / "output.udf").exists() and time.time() < deadline:
        time.sleep(0.05)
    second = run(d, *args[3:], "--overwrite")
    assert first.poll() is None             # the first run was still running
    first.send_signal(signal.SIGTERM)
    _, err1 = first.communicate(timeout=300)
    assert first.returncode == 1 and "interrupted at step" in err1, err1
    assert second.returncode == 2, second.stderr
    assert "another kapsel-py run is writing into" in second.stderr
    out = UDFManager(str(d / "output.udf"))   # one run's records, complete and in order
    steps = []
    for n in range(out.totalRecord()):
        out.jump(n)
        steps.append(out.get("t"))
    assert steps == sorted(steps) and len(set(steps)) == len(steps)
    assert not any(f.startswith(".") for f in os.listdir(d))    # no lock file left


# ---------------------------------------------------------------- 6. symlinks, special files
def test_symlink_and_special_files_are_never_replaced(tmp_path, capsys, monkeypatch):
    d = small(tmp_path)
    target = tmp_path / "elsewhere.udf"
    target.write_text("keep me\n")
    os.symlink(target, d / "link.udf")
    os.mkfifo(d / "fifo.udf")
    monkeypatch.chdir(d)
    base = ["-Iinput.udf", "-Ddefine.udf", "--quiet", "--overwrite"]
    assert main(base + ["-Olink.udf", "-Rrestart.udf"]) == 2
    assert "-Olink.udf: is a symbolic link" in capsys.readouterr().err
    assert os.path.islink(d / "link.udf") and target.read_text() == "keep me\n"
    assert main(base + ["-Ooutput.udf", "-Rfifo.udf"]) == 2
    assert "-Rfifo.udf: is a FIFO, not a regular file" in capsys.readouterr().err
    assert stat.S_ISFIFO(os.stat(d / "fifo.udf").st_mode)
    assert main(base + ["-O/dev/null", "-Rrestart.udf"]) == 2
    assert "-O/dev/null: is a device node" in capsys.readouterr().err
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    assert not (d / "restart.udf").exists() and not (d / "output.udf").exists()


# ---------------------------------------------------------------- 5. tracebacks
def test_negative_seed_is_refused(tmp_path):
    d = small(tmp_path)
    r = run(d, "-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--seed", "-1")
    assert r.returncode == 2 and "--seed must be an integer from 0" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr


def test_ctrl_c_during_start_up(tmp_path):
    """SIGINT while the input is read and the model is built (32^3: about a second)."""
    d = small(tmp_path, npx=5)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.Popen(KAPSEL + ["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf",
                                      "-Rrestart.udf", "--quiet"],
                            cwd=d, stderr=subprocess.PIPE, text=True, env=env)
    time.sleep(0.4)                      # past the interpreter's own start, inside main()
    proc.send_signal(2)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 1, err
    assert "Traceback" not in err and "interrupted during start-up" in err, err
    assert not (d / "output.udf").exists()


# ---------------------------------------------------------------- 4. another run's output
def test_continuation_refuses_another_runs_output(tmp_path, capsys, monkeypatch):
    a = small(tmp_path, "a", nsnap=3)
    b = small(tmp_path, "b", nsnap=3)
    assert cli(a, "input.udf") == 0
    assert cli(b, "input.udf") == 0
    theirs = (b / "output.udf").read_bytes()
    rs = UDFManager(str(a / "restart.udf"))
    rs.put(5, "output.Num_snap")
    rs.write(str(a / "restart.udf"))          # same data: the state file still matches
    monkeypatch.chdir(a)
    assert main(["-Irestart.udf", f"-O{b / 'output.udf'}", "-Ddefine.udf", "-Rrestart.udf",
                 "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "belongs to another run" in err and "--overwrite" in err
    assert (b / "output.udf").read_bytes() == theirs
    # its own output.udf is accepted and continued
    assert main(["-Irestart.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                 "--quiet"]) == 0
    assert UDFManager(str(a / "output.udf")).totalRecord() == 6


# ---------------------------------------------------------------- 9. seed, finished runs
def test_quiet_run_records_its_seed_and_reproduces(tmp_path):
    d = small(tmp_path, nsnap=2, kBT=0.5)     # with thermal noise: the seed matters
    r = run(d, "-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--quiet")
    assert r.returncode == 0 and r.stderr == "", r.stderr
    first = (d / "output.udf").read_text().splitlines()[0]
    assert first.startswith("// kapsel-py run ") and "random seed " in first
    seed = int(first.split("random seed ")[1].split()[0])
    with np.load(state_path(str(d / "restart.udf"))) as z:
        assert str(z["seed"]) == f'"{seed}"'
    again = small(tmp_path, "again", nsnap=2, kBT=0.5)
    r = run(again, "-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--quiet",
            "--seed", str(seed))
    assert r.returncode == 0, r.stderr
    body = lambda p: p.read_text().split("\n", 1)[1]       # noqa: E731  (after the run line)
    assert body(d / "output.udf") == body(again / "output.udf")


def test_continuing_a_finished_run_says_so(tmp_path, capsys, monkeypatch):
    d = small(tmp_path, nsnap=2)
    assert cli(d, "input.udf") == 0
    before = {p.name: p.read_bytes() for p in d.iterdir()}
    monkeypatch.chdir(d)
    assert main(["-Irestart.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                 "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "holds the end of its run" in err and "raise output.Num_snap in restart.udf" in err
    assert {p.name: p.read_bytes() for p in d.iterdir()} == before


# ---------------------------------------------------------------- 3. torn tail
def test_torn_last_record_is_dropped_and_the_run_continues(tmp_path, capsys, monkeypatch):
    import warnings
    from udf.manager import TornTailWarning
    d = small(tmp_path, nsnap=3)
    assert cli(d, "input.udf") == 0
    text = (d / "output.udf").read_text()
    last = text.rindex("\\begin{record}")
    # the run had written half of a fourth record when the power went
    (d / "output.udf").write_text(text + text[last:last + (len(text) - last) // 2])
    with pytest.warns(TornTailWarning, match="last record is incomplete"):
        out = UDFManager(str(d / "output.udf"))
    assert out.totalRecord() == 4 and out.torn_tail > 0
    rs = UDFManager(str(d / "restart.udf"))
    rs.put(5, "output.Num_snap")
    rs.write(str(d / "restart.udf"))
    monkeypatch.chdir(d)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["-Irestart.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf"]) == 0
    assert "its last record was incomplete" in capsys.readouterr().err
    out = UDFManager(str(d / "output.udf"))
    assert out.totalRecord() == 6 and out.torn_tail == 0


def test_a_failed_append_leaves_no_torn_record(tmp_path, monkeypatch):
    from kapsel.io import records
    path = tmp_path / "f.udf"
    path.write_bytes(b"complete\n")
    real = os.write

    def half_then_full(fd, data):
        real(fd, bytes(data[:len(data) // 2]))
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(records.os, "write", half_then_full)
    with pytest.raises(OSError, match="No space left") as e:
        records.append_whole(str(path), b"a record that does not fit\n")
    monkeypatch.undo()
    assert e.value.filename == str(path)
    assert path.read_bytes() == b"complete\n"


# ---------------------------------------------------------------- 5. a full disk
def _small_tmpfs(where, size):
    """Mount a tmpfs of ``size`` at ``where`` (root only); False if that is not possible."""
    os.makedirs(where)
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
                       capture_output=True)
    return r.returncode == 0


def test_full_disk_stops_the_run_and_keeps_the_last_good_restart(tmp_path):
    disk = tmp_path / "disk"
    if not _small_tmpfs(disk, "1500k"):
        pytest.skip("cannot mount a small tmpfs here (the injected ENOSPC test covers it)")
    try:
        make_input(disk, "Navier_Stokes_FDM", ns="explicit_scheme", gts=2, nsnap=200,
                   kBT=0.0)
        r = run(disk, "-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                "--seed", "1", "--quiet")
        assert r.returncode == 1, r.stderr
        assert "the disk is full" in r.stderr and "cannot write" in r.stderr
        assert "holds the last good state" in r.stderr and "Traceback" not in r.stderr
        saved = tmp_path / "saved"
        shutil.copytree(disk, saved)
    finally:
        subprocess.run(["umount", str(disk)])
    _continue_after_failure(saved)


def test_injected_enospc_keeps_the_last_good_restart(tmp_path, monkeypatch, capsys):
    """The same without a tmpfs: the third restart write fails with ENOSPC."""
    from kapsel.io import restart
    d = small(tmp_path, gts=2, nsnap=6)
    real = restart._savez_tmp
    calls = []

    def savez(path, arrays):
        calls.append(path)
        if len(calls) == 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(path, arrays)
    monkeypatch.setattr(restart, "_savez_tmp", savez)
    monkeypatch.chdir(d)
    assert main(["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                 "--seed", "1", "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "cannot write restart.udf.state.npz at step 4: the disk is full" in err
    assert "(step 2)" in err
    monkeypatch.undo()
    _continue_after_failure(d)


def _continue_after_failure(d):
    from kapsel.io.restart import read_restart
    out = UDFManager(str(d / "output.udf"))
    assert out.torn_tail == 0
    rs = UDFManager(str(d / "restart.udf"))
    saved = read_restart(rs, str(d / "restart.udf"), rs.get("resume.Calculation"))
    assert saved.exact is not None and saved.step > 0       # the pair still matches
    assert not [f for f in os.listdir(d) if ".tmp" in f]
    rs.put(saved.step // 2 + 1, "output.Num_snap")
    rs.write(str(d / "restart.udf"))
    r = run(d, "-Irestart.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--quiet")
    assert r.returncode == 0, r.stderr
    assert UDFManager(str(d / "output.udf")).totalRecord() == saved.step // 2 + 2


# ---------------------------------------------------------------- 5. damaged state file
@pytest.mark.parametrize("damage", ["corrupt", "truncated", "empty", "directory"])
def test_damaged_state_file_is_said_and_the_run_continues(tmp_path, damage, capsys,
                                                          monkeypatch):
    d = small(tmp_path, nsnap=2)
    assert cli(d, "input.udf") == 0
    st = d / "restart.udf.state.npz"
    data = st.read_bytes()
    if damage == "corrupt":
        st.write_bytes(data[:30] + bytes(200) + data[230:])
    elif damage == "truncated":
        st.write_bytes(data[:len(data) // 2])
    elif damage == "empty":
        st.write_bytes(b"")
    else:
        st.unlink()
        st.mkdir()
    rs = UDFManager(str(d / "restart.udf"))
    rs.put(3, "output.Num_snap")
    rs.write(str(d / "restart.udf"))
    monkeypatch.chdir(d)
    code = main(["-Irestart.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                 "--quiet"])
    err = capsys.readouterr().err
    if damage == "directory":          # it could not be replaced either: refused up front
        assert code == 2 and "state file restart.udf.state.npz is a directory" in err, err
        from kapsel.io.restart import read_restart
        saved = read_restart(UDFManager(str(d / "restart.udf")), str(d / "restart.udf"),
                             "CONTINUE_FDM")
        assert saved.exact is None and saved.state_damaged
    else:
        assert "restart.udf.state.npz is damaged" in err and "restart data alone" in err, err
        assert code == 0, err
        assert UDFManager(str(d / "output.udf")).totalRecord() == 4


# ---------------------------------------------------------------- 8. what blew up first
@pytest.mark.parametrize("item", ["EPSILON", "gravity.G"])
def test_huge_epsilon_or_g_is_named(tmp_path, item, capsys, monkeypatch):
    d = tmp_path / "blow"
    make_input(d, "Navier_Stokes_Cahn_Hilliard_FDM", ns="explicit_scheme", gts=2, nsnap=3,
               kBT=0.0, particles=4)
    u = UDFManager(str(d / "input.udf"))
    u.put(1e12, item)
    u.put(2.0, "object_type.spherical_particle.Particle_spec[0].MASS_RATIO")
    # A 2 in the 16^3 box: LJ_truncate OFF reaches min(16 DX / 2, 2.5 x 2A) = 2 x 2A, as the
    # original's A_R_cutoff (input.cxx); with the sample's A 4 it reaches contact only
    u.put(2.0, "A")
    u.put(1.0, "A_XI")
    u.write(str(d / "input.udf"))
    monkeypatch.chdir(d)
    assert main(["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--seed", "1",
                 "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "the run stopped at step 1: the particle forces" in err, err
    assert "EPSILON or G is too large" in err
    assert err.index("particle forces") < err.index("Cahn-Hilliard")


# ---------------------------------------------------------------- 7. beyond the type's range
def test_value_beyond_float_range_is_refused_at_input(tmp_path, capsys, monkeypatch):
    d = small(tmp_path, particles=1)
    u = UDFManager(str(d / "input.udf"))
    u.put("user_specify", "switch.INIT_distribution.type")
    u.write(str(d / "input.udf"))
    text = (d / "input.udf").read_text()
    key = "{32.0,32.0,32.0},{0.0,0.0,0.0},{0.0,0.0,0.0,0.0}"
    assert key in text
    (d / "input.udf").write_text(text.replace(key, "{1e300,8.0,8.0},{0.0,0.0,0.0},"
                                                   "{1.0,0.0,0.0,0.0}"))
    monkeypatch.chdir(d)
    assert main(["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "1e300 is beyond the range of a float" in err
    assert "user_specify.Particles[0].R.x" in err
    assert not (d / "output.udf").exists()


def test_writer_never_writes_an_unreadable_float():
    from udf.schema import Primitive
    from udf.writer import format_array
    with pytest.raises(ValueError, match="beyond the range"):
        format_array(np.array([1.0, 1e300]), Primitive("float"), 1, single=True)
    assert str(format_array(np.array([1.0, 1e300]), Primitive("double"), 1, single=True)) \
        == "[1.0,1e+300]"


# ---------------------------------------------------------------- 5. more tracebacks
def _include_chain(d, depth):
    """input.udf -> inc1.udf -> ... -> inc<depth>.udf -> define.udf."""
    samples = os.path.join(TESTS, "..", "samples")
    with open(os.path.join(samples, "input.udf")) as fh:      # the manual's, with include
        text = fh.read()
    assert '\\include{"define.udf"}' in text
    (d / "input.udf").write_text(text.replace('\\include{"define.udf"}', '\\include{"inc1.udf"}'))
    for k in range(1, depth + 1):
        nxt = f"inc{k + 1}.udf" if k < depth else "define.udf"
        (d / f"inc{k}.udf").write_text(f'\\include{{"{nxt}"}}\n')


def test_deep_include_chain_is_one_line(tmp_path):
    d = small(tmp_path)
    _include_chain(d, 1200)
    r = run(d, "-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--quiet")
    assert r.returncode == 2, r.stderr
    assert "includes are nested more than 100 deep" in r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.splitlines()) == 1


def test_include_chain_within_the_limit_reads(tmp_path):
    d = small(tmp_path)
    _include_chain(d, 95)
    assert UDFManager(str(d / "input.udf")).get("mesh.NPX") == 5


def test_radius_not_above_half_the_interface_is_refused(tmp_path, capsys, monkeypatch):
    d = small(tmp_path, particles=1)
    u = UDFManager(str(d / "input.udf"))
    u.put(1.0, "A")
    u.put(2.0, "A_XI")
    u.write(str(d / "input.udf"))
    monkeypatch.chdir(d)
    assert main(["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "A = 1.0: must exceed A_XI / 2 = 1" in err and len(err.splitlines()) == 1
