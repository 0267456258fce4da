"""Static structure factor S(q) of the order parameter, as the original's sq_analysis.py.

S(q) is the spherical (shell) average of |FFT(psi - <psi>)|^2 / N over wave vectors with
|k| in [q - dq/2, q + dq/2), dq = 2 pi / L_min; the characteristic wavenumber is the first
moment q1 = sum q S(q) / sum S(q) (the domain size of phase separation is 2 pi / q1).
"""
from __future__ import annotations

import glob
import os
import re

import numpy as np


def structure_factor(psi: np.ndarray, dx: float = 1.0):
    """(q, S(q), counts) of a periodic scalar field indexed [x, y, z]."""
    psi = np.asarray(psi, dtype=float)
    shape = psi.shape
    fk = np.fft.rfftn(psi - psi.mean())
    power = (fk.real ** 2 + fk.imag ** 2) / psi.size
    ks = [2 * np.pi * np.fft.fftfreq(n, d=dx) for n in shape[:-1]]
    ks.append(2 * np.pi * np.fft.rfftfreq(shape[-1], d=dx))
    kx, ky, kz = np.meshgrid(*ks, indexing="ij")
    kmag = np.sqrt(kx ** 2 + ky ** 2 + kz ** 2)
    # rfft stores half the kz modes: weight the ones whose mirror image is not stored
    weight = np.full(kz.shape, 2.0)
    weight[..., 0] = 1.0
    if shape[-1] % 2 == 0:
        weight[..., -1] = 1.0
    dq = 2 * np.pi / (min(shape) * dx)
    shell = np.rint(kmag / dq).astype(np.int64).ravel()
    counts = np.bincount(shell, weights=weight.ravel())
    sums = np.bincount(shell, weights=(power * weight).ravel())
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
    text = open(xmf, encoding="utf-8").read()
    times = re.findall(r'<Time\s+Value="([^"]+)"', text)
    nums = re.findall(r"orderparam_(\d+)\.h5", text)
    return {int(n): float(t) for n, t in zip(nums, times)}


def read_psi(path: str) -> np.ndarray:
    """The first dataset of an orderparam file, as [x, y, z] (files store (NZ, NY, NX))."""
    import h5py
    with h5py.File(path, "r") as f:
        name = "PSI" if "PSI" in f else next(iter(f.keys()))
        return np.ascontiguousarray(np.asarray(f[name]).T)
