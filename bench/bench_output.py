"""Time per snapshot of each kind of output at 64^3 (the manual's sample scene, 8 particles),
against the time of one step: output.udf records, the FDM per-snapshot files, output.AVS
EXTENDED (full grid and cropped) and legacy AVS BINARY / ASCII, for the spectral type and the
two-component FDM type.  Each writer gets fresh snapshots, so the times include computing
what it writes (velocity in real space, pressure, stress, flux) besides the file work; the
'fields' line is that computation alone (u, phi, pressure, tau).  Prints a table.

    .venv/bin/python bench/bench_output.py [--np 6] [--snaps 3]
"""
import argparse
import os
import sys
import tempfile
import time
from types import SimpleNamespace

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from kapsel import config, models  # noqa: E402,F401
from kapsel.typespec import SOLVERS  # noqa: E402
from kapsel.io import writers as wr  # noqa: E402
from udf import UDFManager  # noqa: E402

SAMPLES = os.path.join(os.path.dirname(__file__), "..", "samples")


def scene(tmp, eq, np_, kind=None, crop=False):
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u.put(eq, "constitutive_eq.type")
    for ax in ("NPX", "NPY", "NPZ"):
        u.put(np_, f"mesh.{ax}")
    if kind:
        u.put("ON", "output.AVS")
        u.put(os.path.join(tmp, "avs"), "output.ON.Out_dir")
        u.put(kind, "output.ON.FileType")
        pf = "output.ON.EXTENDED.Print_field"
        for f in ("Vel", "Phi", "Pressure", "Tau"):
            u.put("YES", f"{pf}.{f}")
        u.put("YES" if crop else "NO", f"{pf}.Crop")
        n = 2 ** np_
        for ax in "xyz":
            u.put([0, n // 2, 2], f"{pf}.YES.Slab_{ax}")
    path = os.path.join(tmp, "input.udf")
    u.write(path)
    return path


def size(d):
    return sum(os.path.getsize(os.path.join(r, f)) for r, _, fs in os.walk(d) for f in fs)


def time_writer(make, model, snaps, d=None):
    """(min seconds per write, MB one snapshot adds to directory d)."""
    w = make()
    w.open(model.snapshot(), False)
    t = []
    mb = None
    for k in range(snaps):
        s = model.snapshot()
        before = size(d) if d and k == 0 else 0
        t0 = time.perf_counter()
        w.write(s)
        t.append(time.perf_counter() - t0)
        if d and k == 0:
            mb = (size(d) - before) / 1e6
    w.close("end")
    return min(t), mb


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--np", type=int, default=6)
    ap.add_argument("--snaps", type=int, default=3)
    a = ap.parse_args()
    n = 2 ** a.np
    print(f"{n}^3, 8 particles; seconds per snapshot (min of {a.snaps})")
    print(f"{'type':>32} {'output':>26} {'s/snapshot':>10} {'x step':>7} {'MB/snap':>7}")
    for eq in ("Navier_Stokes", "Navier_Stokes_Cahn_Hilliard_FDM"):
        with tempfile.TemporaryDirectory() as tmp:
            path = scene(tmp, eq, a.np)
            doc = UDFManager(path)
            cfg = config.from_document(doc, path)
            args = SimpleNamespace(seed=1, quiet=True, threads=1, overwrite=True,
                                   output=os.path.join(tmp, "output.udf"),
                                   define=os.path.join(SAMPLES, "define.udf"),
                                   restart=os.path.join(tmp, "restart.udf"), input=path)
            model = SOLVERS[eq](cfg, args, doc)
            t0 = time.perf_counter()
            model.advance()
            model.advance()
            step = (time.perf_counter() - t0) / 2

            def row(what, sec, mb=None):
                print(f"{eq:>32} {what:>26} {sec:10.3f} {sec / step:7.2f} "
                      + (f"{mb:7.1f}" if mb is not None else f"{'':>7}"))

            row("one step", step)
            t = []
            for _ in range(a.snaps):
                s = model.snapshot()
                t0 = time.perf_counter()
                for name in ("u", "phi", "pressure", "tau"):
                    if s.offers(name):
                        s.get(name)
                t.append(time.perf_counter() - t0)
            row("fields (u phi p tau)", min(t))
            row("output.udf record", *time_writer(
                lambda: wr.RecordWriter(args, doc), model, a.snaps, tmp))
            if cfg.is_fdm:
                from kapsel.io.fields import SnapshotFiles
                d = os.path.join(tmp, "fdm")
                row("FDM per-snapshot files", *time_writer(
                    lambda: SnapshotFiles(d, eq, cfg.mesh.shape, cfg.mesh.DX, cfg.output.GTS,
                                          model.particles.n), model, a.snaps, d))
            for kind, crop in (("EXTENDED", False), ("EXTENDED", True), ("BINARY", False),
                               ("ASCII", False)):
                sub = os.path.join(tmp, f"{kind}{crop}")
                os.makedirs(sub)
                p = scene(sub, eq, a.np, kind, crop)
                c = config.from_document(UDFManager(p), p)
                sargs = SimpleNamespace(**{**vars(args), "output": os.path.join(sub, "o.udf")})
                row(f"AVS {kind}" + (" crop 1/8" if crop else ""), *time_writer(
                    lambda: wr.field_writer(c, sargs, model.snapshot()), model, a.snaps,
                    os.path.join(sub, "avs")))


if __name__ == "__main__":
    main()
