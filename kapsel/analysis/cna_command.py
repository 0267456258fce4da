"""``kapsel-py analyze cna``: CNA labels of the particles of output.udf records, or of the
frames of an XYZ / LAMMPS dump file; counts per record on stdout, labels to CSV or HDF5."""
from __future__ import annotations

import sys
import warnings

import numpy as np

from . import cna as C
from .positions import Frame, read_positions


def udf_frames(path: str, record: str):
    """Frames (positions, periodic box) of the records of a kapsel output.udf."""
    import udf
    u = udf.UDFManager(path)
    eq = u.get("constitutive_eq.type")
    dx = u.get(f"constitutive_eq.{eq}.DX")
    box = np.array([2 ** u.get(f"mesh.{a}") for a in ("NPX", "NPY", "NPZ")], float) * dx
    recs = range(u.totalRecord()) if record == "all" else [int(record)]
    frames = []
    for r in recs:
        u.jump(r)
        R = u.getArray("Particles[].R") if u.size("Particles[]") else np.zeros((0, 3))
        frames.append((r, Frame(np.mod(R, box), box, np.zeros(3))))
    return frames


def default_cutoff(positions, box) -> float:
    """0.5 (1 + sqrt 2) times the median nearest-neighbour distance: between the first and
    second shells of FCC/HCP.  BCC needs --cutoff between its second and third shells."""
    from scipy.spatial import cKDTree
    tree = cKDTree(positions, boxsize=box) if box is not None else cKDTree(positions)
    d, _ = tree.query(positions, k=2)
    return 0.5 * (1 + np.sqrt(2)) * float(np.median(d[:, 1]))


def run(a) -> int:
    try:
        if a.file.endswith(".udf"):
            frames = udf_frames(a.file, a.record)
        else:
            all_frames = read_positions(a.file)
            sel = range(len(all_frames)) if a.record == "all" else [int(a.record)]
            frames = [(i, all_frames[i]) for i in sel]
    except (ValueError, IndexError, OSError) as e:
        print(f"kapsel-py analyze cna: error: {e}", file=sys.stderr)
        return 2
    except Exception as e:  # UDFError and friends: one line, no traceback
        print(f"kapsel-py analyze cna: error: {e}", file=sys.stderr)
        return 2
    rows = []
    print("record " + " ".join(f"{name:>8}" for name in C.NAMES.values()) + "   cutoff")
    for rec, fr in frames:
        if len(fr.positions) < 2:
            print(f"{rec:6d}  (fewer than 2 particles)")
            continue
        rc = a.cutoff or default_cutoff(fr.positions, fr.box)
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            labels = C.cna(fr.positions, fr.box, rc, periodic=fr.periodic)
        for item in w:
            print(f"warning (record {rec}): {item.message}", file=sys.stderr)
        cnt = C.counts(labels)
        print(f"{rec:6d} " + " ".join(f"{cnt.get(n, 0):8d}" for n in C.NAMES.values())
              + f"   {rc:.4g}")
        rows.append((rec, labels))
    if a.labels:
        if a.labels.endswith((".h5", ".hdf5")):
            import h5py
            with h5py.File(a.labels, "w") as f:
                for rec, labels in rows:
                    f[f"record_{rec}"] = labels
                f.attrs["names"] = [f"{k}={v}" for k, v in C.NAMES.items()]
        else:
            with open(a.labels, "w", encoding="utf-8") as fh:
                fh.write("record,particle,label,structure\n")
                for rec, labels in rows:
                    for i, lab in enumerate(labels.tolist()):
                        fh.write(f"{rec},{i},{lab},{C.NAMES[lab]}\n")
        print(f"labels written to {a.labels}")
    return 0
