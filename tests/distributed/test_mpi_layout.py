"""The distributed layout's pieces of a Lees-Edwards run against the one-process functions
(tests/distributed/mpi_layout_probe.py under mpiexec): the oblique <-> rectangular re-gridding of a
rank's block is that of the whole field cut to the block, bit for bit; ``near_rows`` under
Lees-Edwards images finds the particles whose rectangular-grid stencil meets the block, and
the particle table's halos (Owned.destinations) bring every such particle and every pair
partner across the images to the rank (checked failing with the images ignored or their x
shift reversed).  ~7 s per case."""
import os
import subprocess
import sys

import pytest

from builders import MPIEXEC

pytestmark = pytest.mark.skipif(MPIEXEC is None, reason="the mpi extra is not installed")
PROBE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "mpi_layout_probe.py")


@pytest.mark.parametrize("n, px, py", [(2, 2, 1), (4, 2, 2), (3, 3, 1)])
def test_layout_regridding_and_near_rows_under_lees_edwards_images(tmp_path, n, px, py):
    r = subprocess.run([MPIEXEC, "-n", str(n), sys.executable, PROBE, str(px), str(py)],
                       cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert (tmp_path / "ok.txt").read_text().startswith(f"{n * 32} re-griddings")
