"""UDF read/write speed: a restart-sized file (U of 128^3 x 3 floats, about 6.3 M numbers) and
an output file with 200 records of 4096 particles.  Prints a table.

    .venv/bin/python bench/bench_udf.py [--n 128] [--records 200] [--particles 4096]
"""
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")      # single-threaded BLAS, as kapsel-py runs (kapsel.cli)

import argparse
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from udf import UDFManager  # noqa: E402

DEFINE = os.path.join(os.path.dirname(__file__), "..", "samples", "define.udf")


def restart_case(tmp, n):
    u = UDFManager(schema_from=DEFINE)
    rng = np.random.default_rng(0)
    base = "resume.CONTINUE_FDM.Saved_Data"
    u.put("CONTINUE_FDM", "resume.Calculation")
    u.put(rng.standard_normal((n, n, n, 3)), base + ".U[]")
    path = os.path.join(tmp, "restart.udf")
    t0 = time.perf_counter()
    u.write(path)
    tw = time.perf_counter() - t0
    t0 = time.perf_counter()
    v = UDFManager(path)
    arr = v.getArray(base + ".U[]")
    tr = time.perf_counter() - t0
    assert arr.shape == (n, n, n, 3)
    return "restart U %d^3x3 (%.1f M numbers, %.0f MB)" % (n, arr.size / 1e6,
                                                             os.path.getsize(path) / 1e6), tw, tr


def output_case(tmp, nrec, npart):
    u = UDFManager(schema_from=DEFINE)
    u.single_precision_records = True  # as KAPSEL writes output.udf (OCTA float)
    rng = np.random.default_rng(1)
    for r in range(nrec):
        u.newRecord(f"step {r}")
        u.put(1.0, "E")
        u.put(float(r), "t")
        u.put(rng.standard_normal((npart, 34)), "Particles[]")
    path = os.path.join(tmp, "output.udf")
    t0 = time.perf_counter()
    u.write(path)
    tw = time.perf_counter() - t0
    t0 = time.perf_counter()
    v = UDFManager(path)
    for r in range(v.totalRecord()):
        v.jump(r)
        R = v.getArray("Particles[].R")
    tr = time.perf_counter() - t0
    assert R.shape == (npart, 3) and v.totalRecord() == nrec
    return "output %d records x %d particles (%.0f MB)" % (nrec, npart,
                                                          os.path.getsize(path) / 1e6), tw, tr


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=128)
    ap.add_argument("--records", type=int, default=200)
    ap.add_argument("--particles", type=int, default=4096)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        rows = [restart_case(tmp, a.n), output_case(tmp, a.records, a.particles)]
    print("%-52s %10s %10s" % ("case", "write [s]", "read [s]"))
    for name, tw, tr in rows:
        print("%-52s %10.2f %10.2f" % (name, tw, tr))


if __name__ == "__main__":
    main()
