"""The analysis outputs under kills and full disks (issue 26): ``analyze sq`` (its table and
its plot), ``analyze cna --labels`` (HDF5 and CSV) and ``analyze show`` (one PNG per record)
killed with SIGKILL at a write / rename / fsync of their outputs (strace's fault injection,
tests/kill_points.py), then run again: the second run exits 0, leaves the files of an
uninterrupted run byte for byte, and no temporary file (what the killed run left is removed
by the next run of the analysis: udf.files.remove_temporaries_of).  ENOSPC at a write:
one line naming the file and the full disk, exit 1, the old file (if any) kept.

The fast test takes the middle call of each command; the ``slow`` sweep takes every call
(counts and times in docs/restart.md)."""
import os
import shutil

import h5py
import numpy as np
import pytest

import kill_points as kp

from builders import one_line


pytestmark = pytest.mark.skipif(not kp.have_strace(), reason="strace is not installed "
                                "(make test installs it)")


def _sq(d):
    for n in (0, 1):
        with h5py.File(os.path.join(d, f"orderparam_{n}.h5"), "w") as f:
            f["PSI"] = np.random.default_rng(n).standard_normal((8, 8, 8))
    return ["analyze", "sq", ".", "--table", "sq.txt", "--plot", "sq.png"]


def _cna(d):
    base = np.array([[0, 0, 0], [.5, .5, 0], [.5, 0, .5], [0, .5, .5]])
    pts = np.array([(np.array([i, j, k]) + b) * 2.0 for i in range(3) for j in range(3)
                    for k in range(3) for b in base])
    with open(os.path.join(d, "fcc.xyz"), "w") as fh:
        fh.write(f'{len(pts)}\nLattice="6 0 0 0 6 0 0 0 6"\n')
        fh.writelines(f"A {x} {y} {z}\n" for x, y, z in pts)
    return ["analyze", "cna", "fcc.xyz", "--labels", "labels.h5"]


def _show(d):
    from builders import make_input
    make_input(d, "Navier_Stokes_Cahn_Hilliard_FDM", ns="explicit_scheme",
               ch="explicit_scheme", particles=1, gts=2, nsnap=1, kBT=0.0, npx=3)
    from udf import UDFManager
    u = UDFManager(os.path.join(d, "input.udf"))
    u.put(2.0, "A")
    u.put(1.0, "A_XI")
    u.write(os.path.join(d, "input.udf"))
    r = kp.run(d, kp.command())
    assert r.returncode == 0, r.stderr
    return ["analyze", "show", ".", "--record", "all", "--out", "pictures"]


COMMANDS = {"sq": _sq, "cna": _cna, "show": _show}


class Case:
    def __init__(self, root, name):
        self.base = os.path.join(root, "base")
        os.makedirs(self.base)
        self.cmd = kp.KAPSEL + COMMANDS[name](self.base)
        if name == "show":
            os.makedirs(os.path.join(self.base, "pictures"))
        self.ref = os.path.join(root, "ref")
        shutil.copytree(self.base, self.ref)
        # the calls that write the outputs (not the run that made show's input)
        self.calls = [c for c in kp.trace(self.ref, self.cmd)
                      if not c[2].startswith(("write(1<", "write(2<"))]


@pytest.fixture(scope="module", params=list(COMMANDS))
def case(request, tmp_path_factory):
    return Case(str(tmp_path_factory.mktemp(request.param)), request.param)


def _kill(case, kind, n):
    d = os.path.join(os.path.dirname(case.ref), f"kill-{kind}-{n}")
    if os.path.exists(d):
        shutil.rmtree(d)
    shutil.copytree(case.base, d)
    first = kp.run(d, case.cmd, ["-o", "/dev/null", "-e", f"inject={kind}:signal=KILL:when={n}"])
    assert first.returncode == -9, first.stderr
    again = kp.run(d, case.cmd)
    assert again.returncode == 0, again.stderr
    assert kp.compare_runs(case.ref, d) == []
    assert kp.temporaries(d) == []
    shutil.rmtree(d)


def _enospc(case, kind, n):
    d = os.path.join(os.path.dirname(case.ref), f"enospc-{kind}-{n}")
    if os.path.exists(d):
        shutil.rmtree(d)
    shutil.copytree(case.ref, d)          # the outputs exist: a failed write keeps them
    first = kp.run(d, case.cmd, ["-o", "/dev/null", "-e",
                                 f"inject={kind}:error=ENOSPC:when={n}"])
    if first.returncode == 0:              # a write whose failure nothing sees (stdout)
        assert kp.compare_runs(case.ref, d) == []
    else:
        assert first.returncode == 1, first.stderr
        assert "the disk is full" in one_line(first.stderr)
        assert kp.compare_runs(case.ref, d) == []
    assert kp.temporaries(d) == []
    shutil.rmtree(d)


def _points(case, kinds=("write", "pwrite64", "rename", "fsync")):
    return [(k, n) for k, n, _ in case.calls if k in kinds]


def test_kill_and_enospc_in_the_middle_of_an_analysis_write(case):
    points = _points(case)
    _kill(case, *points[len(points) // 2])
    writes = _points(case, ("write", "pwrite64"))
    _enospc(case, *writes[len(writes) // 2])


@pytest.mark.slow
def test_kill_and_enospc_at_every_call_of_an_analysis(case):
    bad = []
    for kind, n in _points(case):
        try:
            _kill(case, kind, n)
        except AssertionError as e:
            bad.append(("kill", kind, n, str(e)[:300]))
    for kind, n in _points(case, ("write", "pwrite64", "fsync")):
        try:
            _enospc(case, kind, n)
        except AssertionError as e:
            bad.append(("ENOSPC", kind, n, str(e)[:300]))
    assert bad == []
