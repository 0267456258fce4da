"""Static structure factor S(q) of the order parameter, as the sample's sq_analysis.py.

S(q) is the shell average of |FFT(psi - <psi>)|^2 / N over wave vectors with |k| / dq in
[i - 1/2, i + 1/2), dq = 2 pi / L_min, for the complete shells i < N_min / 2 (as
sq_analysis.py: beyond q = pi / DX the shells are cut by the cube's faces); the
characteristic wavenumber is the first moment q1 = sum q S(q) / sum S(q) over the shells
(the domain size of phase separation is 2 pi / q1).

sq_analysis.py averages over the wave vectors of one octant only (its r is measured from
the array corner, so it takes n_x, n_y, n_z = 0 .. N/2 - 1 and none of the negative
frequencies): a quarter of the independent modes, and for an anisotropic pattern (sheared
domains, lamellae off the axes) a biased average.  kapsel-py averages over every wave
vector of the shell by default; ``octant=True`` (``analyze sq --octant``) reproduces the
script's numbers exactly.  For isotropic domains the two agree within the sampling noise
of the shells (a few % at late times on 32^3, tests/integration/test_sq_analysis.py).
"""
from __future__ import annotations

import glob
import os
import re

import numpy as np


def structure_factor(psi: np.ndarray, dx: float = 1.0, octant: bool = False):
    """(q, S(q), counts) of a periodic scalar field indexed [x, y, z] over the complete
    shells 0 < i < N_min / 2 (module docstring); ``octant``: only wave vectors with every
    n_a in 0 .. N_a / 2 - 1, as sq_analysis.py."""
    psi = np.asarray(psi, dtype=float)
    shape = psi.shape
    fk = np.fft.rfftn(psi - psi.mean())
    power = (fk.real ** 2 + fk.imag ** 2) / psi.size
    dq = 2 * np.pi / (min(shape) * dx)
    imax = min(shape) // 2                       # shells i < imax (sq_analysis: NX / 2)
    if octant:
        h = [n // 2 for n in shape]
        power = power[:h[0], :h[1], :h[2]]
        m = np.meshgrid(*[np.arange(k) * min(shape) / n for k, n in zip(h, shape)],
                        indexing="ij")
        weight = np.ones(power.shape)
    else:
        ms = [np.fft.fftfreq(n, 1.0 / n) for n in shape[:-1]]
        ms.append(np.fft.rfftfreq(shape[-1], 1.0 / shape[-1]))
        m = np.meshgrid(*[mi * min(shape) / n for mi, n in zip(ms, shape)], indexing="ij")
        # rfft stores half the kz modes: weight the ones whose mirror image is not stored
        weight = np.full(power.shape, 2.0)
        weight[..., 0] = 1.0
        if shape[-1] % 2 == 0:
            weight[..., -1] = 1.0
    r = np.sqrt(m[0] ** 2 + m[1] ** 2 + m[2] ** 2)
    shell = np.floor(r + 0.5).astype(np.int64).ravel()     # r in [i - 1/2, i + 1/2)
    inside = shell < imax
    counts = np.bincount(shell[inside], weights=weight.ravel()[inside], minlength=imax)
    sums = np.bincount(shell[inside], weights=(power * weight).ravel()[inside],
                       minlength=imax)
    q = np.arange(counts.size) * dq
    keep = (counts > 0) & (q > 0)
    return q[keep], sums[keep] / counts[keep], counts[keep]


def characteristic_wavenumber(q: np.ndarray, s: np.ndarray) -> float:
    total = s.sum()
    return float((q * s).sum() / total) if total > 0 else float("nan")


def snapshot_files(directory: str) -> list:
    """orderparam_<n>.h5 files of a run, ordered by n."""
    files = glob.glob(os.path.join(directory, "orderparam_*.h5"))
    def num(f):
        m = re.search(r"orderparam_(\d+)\.h5$", f)
        return int(m.group(1)) if m else -1
    return sorted((f for f in files if num(f) >= 0), key=num)


def snapshot_times(directory: str) -> dict:
    """Snapshot number -> time, from fluid_phase.xmf (orderparam.xmf of older kapsel-py
    runs) when present."""
    for name in ("fluid_phase.xmf", "orderparam.xmf"):
        xmf = os.path.join(directory, name)
        if os.path.exists(xmf):
            break
    else:
        return {}
    from udf.files import open_regular
    with open_regular(xmf, "r", encoding="utf-8") as fh:
        text = fh.read()
    times = re.findall(r'<Time\s+Value="([^"]+)"', text)
    nums = re.findall(r"orderparam_(\d+)\.h5", text)
    return {int(n): float(t) for n, t in zip(nums, times)}


def read_psi(path: str) -> np.ndarray:
    """The first dataset of an orderparam file, as [x, y, z] (files store (NZ, NY, NX))."""
    import h5py

    from udf.files import check_regular
    check_regular(path)
    with h5py.File(path, "r") as f:
        name = "PSI" if "PSI" in f else next(iter(f.keys()))
        psi = np.asarray(f[name])
    if psi.ndim != 3 or psi.dtype.kind not in "fiu" or 0 in psi.shape:
        raise ValueError(f"its dataset {name} is not a 3-D numeric field (shape "
                         f"{psi.shape}, type {psi.dtype})")
    return np.ascontiguousarray(psi.T)
