"""Kill a run at exact system calls, or make them fail with ENOSPC, and continue it
(tests/kill_points.py; strace's fault injection, installed by ``make test``).

Three inputs, all 8^3 with noise: Navier_Stokes (spectral) with output.AVS EXTENDED,
Navier_Stokes_FDM (per-snapshot .h5 and .xmf files), and Shear_Navier_Stokes_Lees_Edwards
with a rigid rod and legacy AVS (shear_stress.dat, rotational_energy.dat, the .fld/.dat
files); GTS 2, Num_snap 3; and the FDM input run on 2 ranks (mpiexec, rank 0 -- the rank
that writes -- under strace, the continuation on 2 ranks again).  The windows: every
write / pwrite64 / rename / fsync of the snapshot at step 4 (output.udf record, field files,
EXTENDED frame and its journal, .conf/.xdmf, checkpoint), and of the end of the run (final
restart pair, closing the trajectory).

The fast tests take two kill points and one ENOSPC point of each input (the rename of
restart.udf after its state file's, a write of the EXTENDED frame or of a per-snapshot .h5
file); the ``slow`` sweeps take every call (counts and times in docs/restart.md, "Kills and full
disks").
"""
import os
import re
import shutil

import numpy as np
import pytest

import kill_points as kp

from builders import copy_schema, one_line


pytestmark = pytest.mark.skipif(not kp.have_strace(), reason="strace is not installed "
                                "(make test installs it)")


def _spectral(d):
    from builders import sample_input
    u = sample_input(d, "Navier_Stokes", 3)
    u.put(0.5, "constitutive_eq.Navier_Stokes.kBT")
    u.put(2.0, "A")
    u.put(1.0, "A_XI")
    u.put(2, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put(2, "output.GTS")
    u.put(3, "output.Num_snap")
    u.put("ON", "output.AVS")
    u.put("EXTENDED", "output.ON.FileType")
    u.put("NO", "output.ON.EXTENDED.Print_field.Crop")
    u.write(os.path.join(d, "input.udf"))


def _fdm(d):
    from builders import make_input
    from udf import UDFManager
    make_input(d, "Navier_Stokes_FDM", ns="explicit_scheme", gts=2, nsnap=3, kBT=0.5, npx=3)
    u = UDFManager(os.path.join(d, "input.udf"))
    u.put(2.0, "A")
    u.put(1.0, "A_XI")
    u.write(os.path.join(d, "input.udf"))


def _sheared_rigid_avs(d):
    """The writers the other two do not have: shear_stress.dat, rotational_energy.dat and
    the legacy AVS files (Shear_Navier_Stokes_Lees_Edwards, AC shear, one free rigid rod of
    3 beads, noise)."""
    import sys
    sys.path.insert(0, os.path.join(kp.ROOT, "bench"))
    from parity import LE, common, merge, rigid, row, shear
    from udf import UDFManager
    base = os.path.join(kp.ROOT, "samples", "kapsel-udf", "ex14")     # define.udf 4.1
    os.makedirs(d, exist_ok=True)
    copy_schema(d, base)
    u = UDFManager(os.path.join(base, "input.udf"))
    edits = merge(common(LE, n=3, dt=0.05, gts=2, objects="rigid"),
                  rigid([row((2.0 + 2.0 * b, 4.0, 4.0)) for b in range(3)], 3, mass=1.0),
                  shear(LE, rate=0.01, ac=True, freq=0.01),
                  {"A": 1.5, "A_XI": 1.0, f"constitutive_eq.{LE}.kBT": 0.5,
                   "output.Num_snap": 3, "output.AVS": "ON", "output.ON.Out_dir": "avs",
                   "output.ON.Out_name": "data", "output.ON.FileType": "BINARY"})
    for k, v in edits.items():
        u.put(np.array(v, dtype=float) if isinstance(v, list) and v and isinstance(v[0], list)
              else v, k)
    u.write(os.path.join(d, "input.udf"))


# name: (input, ranks); the 2-rank run is killed on rank 0, the rank that writes
INPUTS = {"spectral-EXTENDED": (_spectral, 1), "FDM": (_fdm, 1),
          "sheared-rigid-AVS": (_sheared_rigid_avs, 1), "FDM-2-ranks": (_fdm, 2)}


def _can_run(name) -> bool:
    if INPUTS[name][1] == 1:
        return True
    try:
        import mpi4py  # noqa: F401
    except ImportError:
        return False
    return kp.mpiexec() is not None


class Case:
    """A fresh input, its uninterrupted run, and the calls of its windows."""

    def __init__(self, root, name):
        self.base = os.path.join(root, "base")
        build, self.ranks = INPUTS[name]
        build(self.base)
        self.ref = os.path.join(root, "ref")
        shutil.copytree(self.base, self.ref)
        self.calls = kp.trace(self.ref, kp.command(), self.ranks)   # the uninterrupted run
        self.snapshot, self.final = kp.windows(self.calls, 4)

    def check_numbering(self) -> None:
        """A second run of the input makes the same calls (the kill points are numbered
        on the first)."""
        d = self.ref + "-again"
        shutil.copytree(self.base, d)
        again = kp.trace(d, kp.command(), self.ranks)
        shutil.rmtree(d)
        assert [c[:2] for c in again] == [c[:2] for c in self.calls], \
            "the system calls of two runs of one input differ: cannot number them"


@pytest.fixture(scope="module", params=list(INPUTS))
def case(request, tmp_path_factory):
    if not _can_run(request.param):
        pytest.skip("the mpi extra (mpi4py, mpiexec) is not installed")
    return Case(str(tmp_path_factory.mktemp(request.param)), request.param)


def _kill(case, kind, n):
    first, cont, d = kp.kill_and_continue(case.base, case.ref, kp.command(), kind, n,
                                          ranks=case.ranks)
    # SIGKILL at that call (mpiexec reports its rank's signal as exit 9)
    assert first.returncode == (-9 if case.ranks == 1 else 9), first.stderr
    assert cont.returncode == 0, cont.stderr
    assert "Traceback" not in cont.stderr
    assert kp.compare_runs(case.ref, d) == []
    assert kp.temporaries(d) == []
    shutil.rmtree(d)


def _enospc(case, kind, n):
    first, _, d = kp.kill_and_continue(case.base, case.ref, kp.command(), kind, n,
                                       inject="error=ENOSPC", ranks=case.ranks)
    if first.returncode == 0:       # a write whose failure nothing sees (stderr): nothing
        assert kp.compare_runs(case.ref, d) == []       # to say, nothing lost
        shutil.rmtree(d)
        return
    assert first.returncode == 1, first.stderr
    line = one_line(first.stderr)
    assert "the disk is full" in line, line
    assert kp.temporaries(d) == []
    # nothing lost: once space is free, the run continues to the uninterrupted result
    cont = kp.run(d, kp.command("restart.udf", seed=None), ranks=case.ranks) if os.path.exists(
        os.path.join(d, "restart.udf")) else kp.run(d, kp.command() + ["--overwrite"],
                                                    ranks=case.ranks)
    assert cont.returncode == 0, cont.stderr
    assert kp.compare_runs(case.ref, d) == []
    shutil.rmtree(d)


def _points(window, kinds=kp.KINDS):
    return [(k, n) for k, n, _ in window if k in kinds]


def _file_writes(window):
    """The write / pwrite64 / fsync calls on files (not an MPI library's own pipes and
    sockets, where a full disk means nothing: ENOSPC injected there is no disk failure)."""
    return [(k, n) for k, n, t in window if k in ("write", "pwrite64", "fsync")
            and not re.match(r"\w+\(\d+<(socket|pipe):", t)]


def _frame(window):
    """The field writes of a window: the pwrite64 calls of the HDF5 files (EXTENDED frame,
    per-snapshot .h5), or the writes of the legacy AVS files."""
    return _points(window, ("pwrite64",)) or [(k, n) for k, n, t in window
                                              if k == "write" and "/avs/" in t]


def _pick(case):
    """The fast selection: the last two renames of each window (the checkpoint; the state
    file and restart.udf of the final pair: a kill between them is case 2 of issue 26),
    the middle call on the EXTENDED trajectory or a per-snapshot .h5 file, and the fsync
    before the final state rename."""
    out = []
    for window in (case.snapshot, case.final):
        renames = [(k, n) for k, n, t in window if k == "rename"]
        out += renames[-2:]
        frame = _frame(window)
        if frame:
            out.append(frame[len(frame) // 2])
    fsyncs = [(k, n) for k, n, t in case.final if k == "fsync"]
    out.append(fsyncs[len(fsyncs) // 2])
    return sorted(set(out))


def test_kill_between_the_final_renames_and_in_a_frame(case):
    """Fast: SIGKILL at the rename of restart.udf that follows its state file's (issue 26
    case 2) and at the middle pwrite64 of the snapshot (the EXTENDED frame, case 1; a
    per-snapshot .h5 file of the FDM type)."""
    renames = [(k, n) for k, n, _ in case.final if k == "rename"]
    pw = _frame(case.snapshot)
    for kind, n in (renames[-1], pw[len(pw) // 2]):
        _kill(case, kind, n)


def test_enospc_in_a_snapshot_is_one_line_and_loses_nothing(case):
    writes = _frame(case.snapshot)
    _enospc(case, *writes[len(writes) // 3])


@pytest.mark.slow
def test_kill_and_enospc_at_chosen_calls(case):
    """The renames, a frame write, the fsync before the final state rename; ENOSPC at the
    first, middle and last write of the snapshot; and the numbering checked."""
    case.check_numbering()
    for kind, n in _pick(case):
        _kill(case, kind, n)
    writes = _points(case.snapshot, ("write", "pwrite64"))
    for kind, n in (writes[0], writes[len(writes) // 2], writes[-1]):
        _enospc(case, kind, n)


def test_every_rename_is_preceded_by_fsync(case):
    """Every file put in place by a rename was synced first (a power loss leaves the old or
    the new file, never an empty one), and so was its directory after."""
    synced = set()
    for i, (kind, _n, text) in enumerate(case.calls):
        if kind == "fsync":
            m = re.search(r"fsync\(\d+<([^>]*)>", text)
            if m:
                synced.add(m.group(1))
        elif kind == "rename":
            src = re.search(r'rename\("([^"]+)"', text).group(1)
            src = os.path.normpath(os.path.join(case.ref, src))
            assert src in synced, f"{text}: not synced before the rename"
            after = case.calls[i + 1]
            assert after[0] == "fsync" and os.path.dirname(src) in after[2], after


@pytest.mark.slow
def test_kill_at_every_call_of_a_snapshot_and_of_the_end(case):
    """Every write/pwrite64/rename/fsync of the two windows (docs/restart.md: about 150 points per
    input, 25-35 min each on 2 busy cores)."""
    bad = []
    for kind, n in _points(case.snapshot) + _points(case.final):
        try:
            _kill(case, kind, n)
        except AssertionError as e:
            bad.append((kind, n, str(e)[:300]))
    assert bad == []


@pytest.mark.slow
def test_enospc_at_every_write_of_a_snapshot_and_of_the_end(case):
    bad = []
    for kind, n in _file_writes(case.snapshot) + _file_writes(case.final):
        try:
            _enospc(case, kind, n)
        except AssertionError as e:
            bad.append((kind, n, str(e)[:300]))
    assert bad == []


def _killed_in_a_frame(case):
    """A copy of the input killed at the middle field write of the snapshot at step 4 (a torn
    file for the continuation to put back): its directory."""
    frame = _frame(case.snapshot)
    kind, n = frame[len(frame) // 2]
    d = case.ref + "-killed"
    if not os.path.exists(d):
        shutil.copytree(case.base, d)
        first = kp.run(d, kp.command(), ["-o", "/dev/null", "-e",
                                         f"inject={kind}:signal=KILL:when={n}"],
                       ranks=case.ranks)
        assert first.returncode == (-9 if case.ranks == 1 else 9), first.stderr
    return d


@pytest.mark.slow
def test_kill_at_every_call_of_a_continuations_start_up(case):
    """A continuation repairs what the killed run left (output.udf's torn tail, the field
    files and .xmf / .xdmf series past the restart, the trajectory's frame): SIGKILL at every
    write / pwrite64 / rename / fsync of that repair, up to the continuation's first record,
    and a second continuation still ends with the uninterrupted run's files, no temporary
    left (measured 2026-12-04: 46 points FDM, 77 spectral-EXTENDED, 106 sheared-rigid-AVS,
    all passing, 2-8 min each)."""
    killed = _killed_in_a_frame(case)
    cont = kp.command("restart.udf", seed=None)
    traced = case.ref + "-traced"
    shutil.copytree(killed, traced)
    calls = kp.trace(traced, cont, case.ranks)
    assert kp.compare_runs(case.ref, traced) == []
    shutil.rmtree(traced)
    first_record = next(i for i, c in enumerate(calls)
                        if c[0] == "write" and '{\\"step ' in c[2])
    bad = []
    for kind, n, _ in calls[:first_record + 1]:
        d = case.ref + f"-cont-{kind}-{n}"
        shutil.copytree(killed, d)
        r = kp.run(d, cont, ["-o", "/dev/null", "-e", f"inject={kind}:signal=KILL:when={n}"],
                   ranks=case.ranks)
        if r.returncode != 0:
            r = kp.run(d, cont, ranks=case.ranks)
        problems = ([f"exit {r.returncode}: {r.stderr[-300:]}"] if r.returncode != 0 else
                    kp.compare_runs(case.ref, d) + kp.temporaries(d)
                    + (["traceback"] if "Traceback" in r.stderr else []))
        if problems:
            bad.append((kind, n, problems))
        else:
            shutil.rmtree(d)
    assert bad == []
