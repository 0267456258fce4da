"""FFTW wisdom kept on disk (kapsel.mesh.wisdom): where it goes, when it is not kept, and that
a shape's plans are stored once (a second planning of the shape writes nothing)."""
import os

import numpy as np
import pytest

from kapsel.mesh import wisdom

pyfftw = pytest.importorskip("pyfftw")


@pytest.fixture
def fresh(monkeypatch):
    """The module's per-process decision made again under the test's environment."""
    monkeypatch.setitem(wisdom._state, "enabled", None)
    yield monkeypatch
    wisdom._state["enabled"] = None


def test_where_the_file_goes(fresh, tmp_path):
    fresh.setenv(wisdom.ENV, str(tmp_path / "w"))
    assert wisdom.path() == str(tmp_path / "w") and wisdom.enabled()
    for off in ("off", "", "0"):
        fresh.setenv(wisdom.ENV, off)
        assert wisdom.path() is None
    fresh.delenv(wisdom.ENV)
    fresh.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    p = wisdom.path()
    assert p.startswith(str(tmp_path / "cache" / "kapsel-py" / "fftw-wisdom-"))
    wisdom._state["enabled"] = None
    assert wisdom.enabled() and not (tmp_path / "cache").exists()   # made when planning
    with wisdom.planning():
        pass
    assert (tmp_path / "cache" / "kapsel-py").is_dir()


def test_a_directory_that_cannot_be_made_keeps_none(fresh, tmp_path):
    (tmp_path / "file").write_text("")
    fresh.setenv(wisdom.ENV, str(tmp_path / "file" / "w"))     # under a regular file
    assert not wisdom.enabled()
    from kapsel.mesh.grid import auto_planner
    assert auto_planner(32 ** 3) == "FFTW_ESTIMATE"


def test_plans_are_stored_once(fresh, tmp_path):
    w = tmp_path / "w"
    fresh.setenv(wisdom.ENV, str(w))
    shape = (12, 10, 14)                 # a shape no other test plans in this process
    a = pyfftw.empty_aligned(shape, dtype="float64")
    b = pyfftw.empty_aligned(shape[:2] + (shape[2] // 2 + 1,), dtype="complex128")
    with wisdom.planning():
        pyfftw.FFTW(a, b, axes=(0, 1, 2), flags=("FFTW_MEASURE",))
    first = w.read_bytes()
    assert first and os.path.exists(str(w) + ".lock")
    os.utime(w, (0, 0))
    with wisdom.planning():              # the same problem: taken from the wisdom
        pyfftw.FFTW(a, b, axes=(0, 1, 2), flags=("FFTW_MEASURE",))
    assert w.stat().st_mtime == 0 and w.read_bytes() == first
    assert not [f for f in os.listdir(tmp_path) if f.endswith(".kapsel-tmp")]
    np.testing.assert_equal(wisdom._state["depth"], 0)


def test_no_locks_reads_plans_and_stores_none(fresh, tmp_path):
    """A file system without locks (flock fails): the stored plans are read, none stored."""
    import fcntl
    w = tmp_path / "w"
    fresh.setenv(wisdom.ENV, str(w))
    w.write_bytes(pyfftw.export_wisdom()[0])
    before = w.read_bytes()

    def no_lock(fd, op):
        raise OSError(37, "No locks available")
    fresh.setattr(fcntl, "flock", no_lock)
    shape = (10, 12, 6)
    a = pyfftw.empty_aligned(shape, dtype="float64")
    b = pyfftw.empty_aligned(shape[:2] + (shape[2] // 2 + 1,), dtype="complex128")
    with wisdom.planning():
        pyfftw.FFTW(a, b, axes=(0, 1, 2), flags=("FFTW_MEASURE",))
    assert w.read_bytes() == before and wisdom._state["depth"] == 0


def _wisdom_only(shape, env):
    """In a new process: plan ``shape`` with FFTW_WISDOM_ONLY inside ``planning`` (works only
    when a stored plan was imported); returns its stdout."""
    import subprocess
    import sys
    code = ("import pyfftw\n"
            "from kapsel.mesh import wisdom\n"
            f"a = pyfftw.empty_aligned({shape}, dtype='float64')\n"
            f"b = pyfftw.empty_aligned({shape[:2] + (shape[2] // 2 + 1,)}, "
            "dtype='complex128')\n"
            "try:\n"
            "    with wisdom.planning():\n"
            "        pyfftw.FFTW(a, b, axes=(0, 1, 2), flags=('FFTW_MEASURE', 'FFTW_WISDOM_ONLY'))\n"
            "    print('stored')\n"
            "except RuntimeError:\n"
            "    print('none')\n")
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    return subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True,
                          text=True, check=True, env=dict(os.environ, **env)).stdout.strip()


def test_a_second_process_takes_the_stored_plan(fresh, tmp_path):
    w = tmp_path / "w"
    shape = (14, 12, 10)
    assert _wisdom_only(shape, {wisdom.ENV: str(w)}) == "none"      # nothing stored yet
    fresh.setenv(wisdom.ENV, str(w))
    a = pyfftw.empty_aligned(shape, dtype="float64")
    b = pyfftw.empty_aligned(shape[:2] + (shape[2] // 2 + 1,), dtype="complex128")
    with wisdom.planning():
        pyfftw.FFTW(a, b, axes=(0, 1, 2), flags=("FFTW_MEASURE",))
    assert _wisdom_only(shape, {wisdom.ENV: str(w)}) == "stored"
    assert _wisdom_only(shape, {wisdom.ENV: "off"}) == "none"


def test_estimate_plans_do_not_read_the_file(fresh, tmp_path):
    """FFTW would take a stored measured plan for an FFTW_ESTIMATE one too: the default plans
    up to 64^3 must give the same bits with or without the file (and as a distributed run's)."""
    fresh.setenv(wisdom.ENV, str(tmp_path / "w"))
    with wisdom.planning(("FFTW_ESTIMATE",)):
        assert wisdom._state["depth"] == 1
    assert not (tmp_path / "w").exists() and not (tmp_path / "w.lock").exists()


def test_measuring_leaves_no_wisdom_in_the_process(fresh, tmp_path):
    """An FFTW_ESTIMATE plan made after a measured one of the same shape has the bits of
    one made in a fresh process (FFTW would otherwise take the measured plan for it)."""
    fresh.setenv(wisdom.ENV, str(tmp_path / "w"))
    shape = (16, 12, 18)
    a = pyfftw.empty_aligned(shape, dtype="float64")
    b = pyfftw.empty_aligned(shape[:2] + (shape[2] // 2 + 1,), dtype="complex128")
    with wisdom.planning():
        pyfftw.FFTW(a, b, axes=(0, 1, 2), flags=("FFTW_MEASURE",))
    with pytest.raises(RuntimeError):            # no wisdom for the shape in the process
        pyfftw.FFTW(a, b, axes=(0, 1, 2), flags=("FFTW_ESTIMATE", "FFTW_WISDOM_ONLY"))
    fresh.setenv(wisdom.ENV, "off")
    wisdom._state["enabled"] = None
    with wisdom.planning():                      # measuring without a file: forgotten too
        pyfftw.FFTW(a, b, axes=(0, 1, 2), flags=("FFTW_MEASURE",))
    with pytest.raises(RuntimeError):
        pyfftw.FFTW(a, b, axes=(0, 1, 2), flags=("FFTW_ESTIMATE", "FFTW_WISDOM_ONLY"))
