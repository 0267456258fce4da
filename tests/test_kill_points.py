"""Kill a run at exact system calls, or make them fail with ENOSPC, and continue it
(tests/kill_points.py; strace's fault injection, installed by ``make test``).

Two inputs, both 8^3 with noise: Navier_Stokes (spectral) with output.AVS EXTENDED, and
Navier_Stokes_FDM (per-snapshot .h5 and .xmf files); GTS 2, Num_snap 3.  The windows: every
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

import pytest

import kill_points as kp
from test_reliability import one_line

pytestmark = pytest.mark.skipif(not kp.have_strace(), reason="strace is not installed "
                                "(make test installs it)")


def _spectral(d):
    from runs import sample_input
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
    from test_restart import make_input
    from udf import UDFManager
    make_input(d, "Navier_Stokes_FDM", ns="explicit_scheme", gts=2, nsnap=3, kBT=0.5, npx=3)
    u = UDFManager(os.path.join(d, "input.udf"))
    u.put(2.0, "A")
    u.put(1.0, "A_XI")
    u.write(os.path.join(d, "input.udf"))


INPUTS = {"spectral-EXTENDED": _spectral, "FDM": _fdm}


class Case:
    """A fresh input, its uninterrupted run, and the calls of its windows."""

    def __init__(self, root, name):
        self.base = os.path.join(root, "base")
        INPUTS[name](self.base)
        self.ref = os.path.join(root, "ref")
        shutil.copytree(self.base, self.ref)
        self.calls = kp.trace(self.ref, kp.command())      # the uninterrupted run
        self.snapshot, self.final = kp.windows(self.calls, 4)

    def check_numbering(self) -> None:
        """A second run of the input makes the same calls (the kill points are numbered
        on the first)."""
        d = self.ref + "-again"
        shutil.copytree(self.base, d)
        again = kp.trace(d, kp.command())
        shutil.rmtree(d)
        assert [c[:2] for c in again] == [c[:2] for c in self.calls], \
            "the system calls of two runs of one input differ: cannot number them"


@pytest.fixture(scope="module", params=list(INPUTS))
def case(request, tmp_path_factory):
    return Case(str(tmp_path_factory.mktemp(request.param)), request.param)


def _kill(case, kind, n):
    first, cont, d = kp.kill_and_continue(case.base, case.ref, kp.command(), kind, n)
    assert first.returncode == -9, first.stderr          # SIGKILL at that call
    assert cont.returncode == 0, cont.stderr
    assert "Traceback" not in cont.stderr
    assert kp.compare_runs(case.ref, d) == []
    assert kp.temporaries(d) == []
    shutil.rmtree(d)


def _enospc(case, kind, n):
    first, _, d = kp.kill_and_continue(case.base, case.ref, kp.command(), kind, n,
                                       inject="error=ENOSPC")
    if first.returncode == 0:       # a write whose failure nothing sees (stderr): nothing
        assert kp.compare_runs(case.ref, d) == []       # to say, nothing lost
        shutil.rmtree(d)
        return
    assert first.returncode == 1, first.stderr
    line = one_line(first.stderr)
    assert "the disk is full" in line, line
    assert kp.temporaries(d) == []
    # nothing lost: once space is free, the run continues to the uninterrupted result
    cont = kp.run(d, kp.command("restart.udf", seed=None)) if os.path.exists(
        os.path.join(d, "restart.udf")) else kp.run(d, kp.command() + ["--overwrite"])
    assert cont.returncode == 0, cont.stderr
    assert kp.compare_runs(case.ref, d) == []
    shutil.rmtree(d)


def _points(window, kinds=kp.KINDS):
    return [(k, n) for k, n, _ in window if k in kinds]


def _pick(case):
    """The fast selection: the last two renames of each window (the checkpoint; the state
    file and restart.udf of the final pair: a kill between them is case 2 of issue 26),
    the middle call on the EXTENDED trajectory or a per-snapshot .h5 file, and the fsync
    before the final state rename."""
    out = []
    for window in (case.snapshot, case.final):
        renames = [(k, n) for k, n, t in window if k == "rename"]
        out += renames[-2:]
        h5 = [(k, n) for k, n, t in window if k == "pwrite64"]
        if h5:
            out.append(h5[len(h5) // 2])
    fsyncs = [(k, n) for k, n, t in case.final if k == "fsync"]
    out.append(fsyncs[len(fsyncs) // 2])
    return sorted(set(out))


def test_kill_between_the_final_renames_and_in_a_frame(case):
    """Fast: SIGKILL at the rename of restart.udf that follows its state file's (issue 26
    case 2) and at the middle pwrite64 of the snapshot (the EXTENDED frame, case 1; a
    per-snapshot .h5 file of the FDM type)."""
    renames = [(k, n) for k, n, _ in case.final if k == "rename"]
    pw = _points(case.snapshot, ("pwrite64",))
    for kind, n in (renames[-1], pw[len(pw) // 2]):
        _kill(case, kind, n)


def test_enospc_in_a_snapshot_is_one_line_and_loses_nothing(case):
    writes = _points(case.snapshot, ("pwrite64",))
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
    for kind, n in _points(case.snapshot, ("write", "pwrite64", "fsync")) + \
            _points(case.final, ("write", "pwrite64", "fsync")):
        try:
            _enospc(case, kind, n)
        except AssertionError as e:
            bad.append((kind, n, str(e)[:300]))
    assert bad == []
