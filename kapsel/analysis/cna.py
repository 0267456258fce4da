"""Common Neighbor Analysis with a fixed cutoff, as LAMMPS compute cna/atom (spec 000).

Per particle i: neighbours N_i = {j != i : |r_ij| < r_c} (eq 1, at most MAXNEAR = 16);
only n_i = 12 or 14 are classified, every other n_i is OTHER.  For each j in N_i the
common neighbours C_ij = N_i ∩ N_j (eq 2, at most MAXCOMMON = 8), the bonds b_ij among
them (eq 3) and the largest / smallest bond degree inside C_ij (eq 4) make the tuple
t_ij = (c, b, Bmax, Bmin) (eq 5), and

    n = 12:  FCC  12 x (4,2,1,1)                 (eq 6)
             HCP   6 x (4,2,1,1) + 6 x (4,2,2,0)  (eq 7)
             ICOS 12 x (5,5,2,2)                 (eq 8)
    n = 14:  BCC   6 x (4,4,2,2) + 8 x (6,6,2,2)  (eq 9)

otherwise OTHER.  UNKNOWN is given only to particles outside ``group`` (as LAMMPS gives
to atoms outside the compute group).

LAMMPS details kept: a particle with more than MAXNEAR = 16 neighbours keeps 16 (here
the 16 nearest) and so, having n = 16, is OTHER (not UNKNOWN), with one warning "too many
neighbours ... for K particles"; more than 8 common neighbours keep the first 8 in i's
neighbour order (here: nearest to i first) with one warning counting such (i, j) pairs;
with no common neighbour Bmax = 0 and Bmin = MAXCOMMON.  Bonds among common neighbours
use the images nearest to i (as LAMMPS does with ghost atoms); periodic boxes must be
longer than 2 r_c.  One deliberate difference: C_ij intersects N_i with j's *full*
neighbour set (eq 2, as OVITO), whereas LAMMPS uses j's list truncated at 16 in its
arbitrary neighbour-list order, so next to a particle with more than 16 neighbours LAMMPS
can give OTHER where this gives FCC/HCP/BCC/ICOS (seen for ~0.1 % of the particles of a
BCC crystal with 8 % noise; elsewhere LAMMPS 2025.7 agreed particle by particle).

The work is whole-array numpy: a cKDTree neighbour table (N, 16), then for each particle
the K x K bond matrix among its K = 12 or 14 neighbours as 16-bit masks; row a of that
matrix *is* C_ij for j = slot a, and degrees are popcounts of masks.
"""
from __future__ import annotations

import warnings

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["UNKNOWN", "FCC", "HCP", "BCC", "ICOS", "OTHER", "NAMES", "MAXNEAR", "MAXCOMMON",
           "CNAWarning", "cna", "counts", "neighbor_table", "fcc_cutoff", "bcc_cutoff"]

UNKNOWN, FCC, HCP, BCC, ICOS, OTHER = 0, 1, 2, 3, 4, 5
NAMES = {UNKNOWN: "UNKNOWN", FCC: "FCC", HCP: "HCP", BCC: "BCC", ICOS: "ICOS", OTHER: "OTHER"}
MAXNEAR = 16
MAXCOMMON = 8


class CNAWarning(UserWarning):
    """Too many neighbours (> MAXNEAR) or common neighbours (> MAXCOMMON), as LAMMPS warns."""


def fcc_cutoff(a: float) -> float:
    """Cutoff halfway between the 1st and 2nd FCC shells, 0.5 (1/sqrt2 + 1) a (also HCP
    with nearest-neighbour distance a/sqrt2)."""
    return 0.5 * (1.0 / np.sqrt(2.0) + 1.0) * a


def bcc_cutoff(a: float) -> float:
    """Cutoff halfway between the 2nd (a) and 3rd (sqrt2 a) BCC shells: 14 neighbours."""
    return 0.5 * (1.0 + np.sqrt(2.0)) * a


# ---------------------------------------------------------------- bit helpers
if hasattr(np, "bitwise_count"):
    def _popcount(x):
        return np.bitwise_count(x)
else:                                                    # numpy < 2.0
    _POP = np.array([bin(v).count("1") for v in range(1 << 16)], dtype=np.uint8)

    def _popcount(x):
        return _POP[x]


def _first8_table() -> np.ndarray:
    """16-bit mask -> the mask keeping only its MAXCOMMON lowest set bits."""
    out = np.arange(1 << 16, dtype=np.uint16)
    while True:                 # clear the highest set bit until MAXCOMMON remain
        more = _popcount(out) > MAXCOMMON
        if not more.any():
            return out
        high = (np.frexp(out[more].astype(np.float64))[1] - 1).astype(np.uint16)
        out[more] &= ~(np.uint16(1) << high)


_FIRST8 = None


def _first8(mask):
    global _FIRST8
    if _FIRST8 is None:
        _FIRST8 = _first8_table()
    return _FIRST8[mask]


def _code(c, b, bmax, bmin):
    return ((np.asarray(c, dtype=np.int32) * 32 + b) * 16 + bmax) * 16 + bmin


_SIG_4211 = int(_code(4, 2, 1, 1))
_SIG_4220 = int(_code(4, 2, 2, 0))
_SIG_5522 = int(_code(5, 5, 2, 2))
_SIG_4422 = int(_code(4, 4, 2, 2))
_SIG_6622 = int(_code(6, 6, 2, 2))


# ---------------------------------------------------------------- geometry
def _prepare(positions, box, cutoff, periodic):
    """Float64 positions wrapped into [0, L) and the cKDTree box (None when open)."""
    p = np.array(positions, dtype=np.float64, copy=True)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"positions must have shape (N, 3), got {p.shape}")
    if not np.isfinite(p).all():
        raise ValueError("positions contain NaN or infinity")
    if not (np.isfinite(cutoff) and cutoff > 0):
        raise ValueError(f"cutoff must be a positive number, got {cutoff}")
    if box is None:
        return p, None
    L = np.broadcast_to(np.asarray(box, dtype=np.float64), (3,)).copy()
    per = np.ones(3, bool) if periodic is None else np.broadcast_to(
        np.asarray(periodic, dtype=bool), (3,)).copy()
    if not per.any():
        return p, None
    for d in range(3):
        if per[d]:
            if not L[d] > 2.0 * cutoff:
                raise ValueError(f"periodic box length {L[d]} along axis {d} must exceed "
                                 f"2 * cutoff = {2 * cutoff} (minimum image)")
            x = p[:, d] - L[d] * np.floor(p[:, d] / L[d])
            x[(x >= L[d]) | (x < 0)] = 0.0
            p[:, d] = x
        else:   # open axis inside a periodic tree: pad so that no image is within r_c
            x = p[:, d] - p[:, d].min() if len(p) else p[:, d]
            L[d] = (x.max() if len(x) else 0.0) + 2.0 * cutoff + 1.0
            p[:, d] = x
    return p, L


def neighbor_table(positions, box=None, cutoff=1.0, max_neighbors=MAXNEAR, periodic=None,
                   chunk=131072):
    """(table (N, max_neighbors) int32 padded with -1, sorted by distance; n (N,) number of
    neighbours kept; overflow (N,) bool: more than max_neighbors within the cutoff) — eq 1."""
    p, L = _prepare(positions, box, cutoff, periodic)
    return _table(p, L, float(cutoff), int(max_neighbors), chunk)


def _table(p, L, rc, kmax, chunk):
    n = len(p)
    tree = cKDTree(p, boxsize=L) if n else None
    table = np.full((n, kmax), -1, dtype=np.int32)
    count = np.zeros(n, dtype=np.int32)
    overflow = np.zeros(n, dtype=bool)
    k = kmax + 2                       # self + kmax + one more to see an overflow
    for s in range(0, n, chunk):
        e = min(n, s + chunk)
        d, idx = tree.query(p[s:e], k=k, distance_upper_bound=rc, workers=1)
        self_ = np.arange(s, e)
        valid = (d < rc) & (idx < n)           # a prefix: cKDTree sorts by distance
        odd = np.flatnonzero(idx[:, 0] != self_)   # i itself not first: coincident points
        if len(odd):
            v = valid[odd] & (idx[odd] != self_[odd, None])
            order = np.argsort(~v, axis=1, kind="stable")
            idx[odd] = np.take_along_axis(idx[odd], order, axis=1)
            valid[odd] = np.take_along_axis(v, order, axis=1)
            idx[odd, 1:] = idx[odd, :-1].copy()      # so that dropping column 0 fits all
            valid[odd, 1:] = valid[odd, :-1].copy()
        idx, valid = idx[:, 1:], valid[:, 1:]
        c = valid.sum(axis=1)
        overflow[s:e] = c > kmax
        count[s:e] = np.minimum(c, kmax)
        table[s:e] = np.where(valid[:, :kmax], idx[:, :kmax], -1)
    return table, count, overflow


# ---------------------------------------------------------------- signatures
def _signatures(pc, L, rc2, table, rows, K, work):
    """Signature codes (M, K) of the tuples t_ij (eqs 2-5) for particles ``rows`` that all
    have K neighbours, and the number of (i, j) with more than MAXCOMMON common neighbours.
    pc: positions as three contiguous coordinate arrays; work: two (>= M, K, K) buffers."""
    m = len(rows)
    nb = table[rows, :K]                                      # (M, K)
    # bond matrix among i's neighbours, computed once (eq 3 test |r_p - r_q| < r_c), with
    # the neighbours' images nearest to i
    d2, tmp = work[0][:m], work[1][:m]
    for ax in range(3):
        x = pc[ax][nb] - pc[ax][rows, None]
        if L is not None:
            x -= L[ax] * np.rint(x / L[ax])
        out = d2 if ax == 0 else tmp
        np.subtract(x[:, :, None], x[:, None, :], out=out)
        np.multiply(out, out, out=out)
        if ax:
            d2 += tmp
    A = d2 < rc2
    A[:, np.arange(K), np.arange(K)] = False                  # j != i
    bits = np.packbits(A, axis=-1, bitorder="little")         # (M, K, 2)
    bits = bits.view("<u2")[..., 0].astype(np.uint16)          # (M, K): row a = C_ij mask
    # row a of the bond matrix is C_ij = N_i ∩ N_j (eq 2) for j = slot a
    ncommon = _popcount(bits)
    too_many = int((ncommon > MAXCOMMON).sum())
    # arrays below are indexed [m, b, a]: b runs over candidate common neighbours of the
    # pair (i, j = slot a); reducing over the middle axis is the fast direction in numpy
    if too_many:
        common = _first8(bits)                                # (M, K)
        member = ((common[:, None, :] >> np.arange(K, dtype=np.uint16)[:, None]) & 1
                  ).astype(bool)
    else:
        common, member = bits, A                              # A is symmetric
    ncommon = np.minimum(ncommon, MAXCOMMON).astype(np.int32)
    # degree of common neighbour b inside C_ij: popcount(bond row b & C_ij)  (eq 4)
    deg = _popcount(bits[:, :, None] & common[:, None, :])    # uint8
    degm = deg * member
    nbond = degm.sum(axis=1, dtype=np.uint8).astype(np.int32) // 2      # eq 3
    bmax = degm.max(axis=1).astype(np.int32)
    bmin = np.where(member, deg, np.uint8(MAXCOMMON)).min(axis=1).astype(np.int32)
    return _code(ncommon, nbond, bmax, bmin), too_many


def cna(positions, box=None, cutoff=1.0, max_neighbors=MAXNEAR, *, periodic=None,
        group=None, chunk=32768, return_neighbors=False):
    """CNA labels (N,) int8 (UNKNOWN/FCC/HCP/BCC/ICOS/OTHER) of spec 000 eqs 1-9.

    positions (N, 3); box (Lx, Ly, Lz) of an orthorhombic periodic box (None: open
    boundaries; ``periodic`` may make some axes open); cutoff r_c; group: optional (N,) bool,
    particles outside it are UNKNOWN (they still count as neighbours).  With
    return_neighbors the neighbour counts n_i (N,), capped at max_neighbors, are returned
    too.  Warns (CNAWarning) as LAMMPS about too many (common) neighbours.
    """
    if max_neighbors != MAXNEAR:
        if not 14 <= int(max_neighbors) <= 64:
            raise ValueError("max_neighbors must be between 14 and 64")
    p, L = _prepare(positions, box, cutoff, periodic)
    rc = float(cutoff)
    n = len(p)
    table, count, overflow = _table(p, L, rc, int(max_neighbors), 131072)
    labels = np.full(n, OTHER, dtype=np.int8)
    if group is not None:
        group = np.asarray(group, dtype=bool)
        if group.shape != (n,):
            raise ValueError(f"group must have shape ({n},), got {group.shape}")
        labels[~group] = UNKNOWN
    nover = int(overflow.sum())
    if nover:
        warnings.warn(f"CNA: too many neighbours (more than {max_neighbors} within the "
                      f"cutoff {rc}) for {nover} particles: they are OTHER",
                      CNAWarning, stacklevel=2)
    ncommon_err = 0
    rc2 = rc * rc
    pc = [np.ascontiguousarray(p[:, ax]) for ax in range(3)]
    for K in (12, 14):
        sel = count == K
        if group is not None:
            sel &= group
        rows_all = np.flatnonzero(sel)
        if not len(rows_all):
            continue
        size = min(chunk, len(rows_all))
        work = (np.empty((size, K, K)), np.empty((size, K, K)))
        for s in range(0, len(rows_all), chunk):
            rows = rows_all[s:s + chunk]
            codes, err = _signatures(pc, L, rc2, table, rows, K, work)
            ncommon_err += err
            if K == 12:
                n4211 = (codes == _SIG_4211).sum(axis=1)
                n4220 = (codes == _SIG_4220).sum(axis=1)
                n5522 = (codes == _SIG_5522).sum(axis=1)
                lab = np.full(len(rows), OTHER, dtype=np.int8)
                lab[n5522 == 12] = ICOS
                lab[(n4211 == 6) & (n4220 == 6)] = HCP
                lab[n4211 == 12] = FCC
            else:
                n4422 = (codes == _SIG_4422).sum(axis=1)
                n6622 = (codes == _SIG_6622).sum(axis=1)
                lab = np.where((n4422 == 6) & (n6622 == 8), BCC, OTHER).astype(np.int8)
            labels[rows] = lab
    if ncommon_err:
        warnings.warn(f"CNA: too many common neighbours (more than {MAXCOMMON}) "
                      f"{ncommon_err} times: the first {MAXCOMMON} were kept",
                      CNAWarning, stacklevel=2)
    if return_neighbors:
        return labels, count
    return labels


def counts(labels) -> dict:
    """Number of particles of each structure, {name: count} over all of NAMES."""
    b = np.bincount(np.asarray(labels, dtype=np.int64).ravel(), minlength=len(NAMES))
    return {NAMES[k]: int(b[k]) for k in sorted(NAMES)}
