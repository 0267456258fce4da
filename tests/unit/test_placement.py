"""Initial placements (table 7 INIT_distribution / INIT_orientation)."""
import os

import numpy as np
import pytest

from kapsel.particles import placement as P
from kapsel.particles import quaternion as Q

from builders import copy_schema, TESTS


BOX = np.array([40.0, 32.0, 48.0])


def _check(R, radius, box, n, gap=P.UNIFORM_GAP):
    """In the box, no two centres within gap (a_i + a_j) (uniform_random's rule, the
    original's 1.05)."""
    assert R.shape == (n, 3)
    assert np.all(R >= 0) and np.all(R < box)
    assert len(P.overlapping_pairs(R, np.asarray(radius) * gap, box)[0]) == 0


@pytest.mark.parametrize("seed", [0, 1])
def test_uniform_random(seed):
    rng = np.random.default_rng(100 + seed)
    radius = rng.uniform(1.5, 3.5, 250)
    R = P.uniform_random(250, radius, BOX, seed)
    assert 0.3 < P.volume_fraction(radius, BOX) < 0.35   # polydisperse, placed largest first
    _check(R, radius, BOX, 250)
    assert np.array_equal(R, P.uniform_random(250, radius, BOX, seed))
    assert not np.array_equal(R, P.uniform_random(250, radius, BOX, seed + 7))


def test_uniform_random_dense_but_possible():
    # volume fraction ~0.3 (below random sequential jamming ~0.38)
    n, a = 110, 2.5
    box = np.array([32.0, 32.0, 24.0])
    assert 0.28 < P.volume_fraction(a, box, n) < 0.33
    _check(P.uniform_random(n, a, box, 3), np.full(n, a), box, n)


def test_uniform_random_impossible():
    box = np.array([20.0, 20.0, 20.0])
    with pytest.raises(ValueError, match="volume fraction 0.49"):   # phi ~ 0.49, RSA jams
        P.uniform_random(60, 2.5, box, 1, max_rounds=30)
    with pytest.raises(ValueError, match="close packing"):
        P.uniform_random(200, 2.5, box, 1)
    with pytest.raises(ValueError, match="larger than the box"):
        P.uniform_random(1, 11.0, box, 1)


ORIGINAL = os.path.join(TESTS, "data",
                        "original_placement.npz")
# record 0 of the original's runs (kref build of kapsel3 8ee457a, 1 thread; the sample input
# with INIT_distribution, Particle_number, A, mesh edited): name -> (kind, n, A, box)
ORIGINAL_CASES = {"bcc60": ("BCC", 60, 4.0, (32, 32, 32)),
                  "bcc54": ("BCC", 54, 2.0, (32, 32, 32)),       # 2 x 3^3: a full lattice
                  "fcc100": ("FCC", 100, 2.0, (32, 32, 32)),
                  "fcc50r": ("FCC", 50, 2.0, (64, 32, 32)),
                  "fcc30r": ("FCC", 30, 2.0, (64, 32, 16)),
                  "fcc120": ("FCC", 120, 2.8, (32, 32, 32)),     # 7 z layers: odd
                  "fcc108": ("FCC", 108, 3.7, (32, 32, 32))}     # every centre relaxed


def _original(name):
    with np.load(ORIGINAL) as z:
        return z[name]


def _min_image(d, box):
    return d - box * np.round(d / box)


@pytest.mark.parametrize("name", ["bcc60", "bcc54", "fcc100", "fcc50r", "fcc30r"])
def test_lattice_sites_are_the_originals(name):
    """Same sites in the same order as the original: BCC exactly (it has no random part);
    FCC within the original's random kick of 0.001 A (no neighbour within the repulsion's
    range here, so nothing else moves)."""
    kind, n, A, box = ORIGINAL_CASES[name]
    box = np.array(box, float)
    c = _original(name)
    if kind == "BCC":
        assert np.array_equal(P.bcc(n, A, box), c)
        return
    sites, _ = P.fcc_sites(n, box)
    d = np.linalg.norm(_min_image(sites - c, box), axis=1)
    assert d.max() <= 1e-3 * A * (1 + 1e-9), d.max()
    R = P.fcc(n, A, box, rng=4, forces=P.repulsion(box, A))
    d = np.linalg.norm(_min_image(R - c, box), axis=1)
    assert d.max() <= 2e-3 * A * (1 + 1e-9)


def test_fcc_relaxation_is_the_originals():
    """An odd number of z layers: the first and last layer meet across the boundary at
    lat_z / 2 < 2A (0.82 of contact); the relaxation pushes them apart by 0.05 A each, as
    the original's (within its kicks).  A denser lattice whose every centre feels the
    nearly cancelling repulsion of its twelve neighbours moves each by 0.05 A in an
    almost random direction, in both programs: pairs end up closer than 2A alike."""
    kind, n, A, box = ORIGINAL_CASES["fcc120"]
    box = np.array(box, float)
    R = P.fcc(n, A, box, rng=1, forces=P.repulsion(box, A))
    c = _original("fcc120")
    assert np.linalg.norm(_min_image(R - c, box), axis=1).max() < 3e-3 * A
    i, j, r = P.overlapping_pairs(R, A, box)
    assert len(i) == 12 and abs(r.min() / (2 * A) - 0.866) < 0.002
    kind, n, A, box = ORIGINAL_CASES["fcc108"]
    box = np.array(box, float)
    sites, lat = P.fcc_sites(n, box)
    assert lat.min() / np.sqrt(2) > 2 * A          # the lattice itself: no pair below 2A
    c = _original("fcc108")
    moved = np.linalg.norm(_min_image(c - sites, box), axis=1)
    assert np.allclose(moved, 0.05 * A, atol=2e-3 * A)      # the original: 0.05 A each
    R = P.fcc(n, A, box, rng=1, forces=P.repulsion(box, A))
    moved = np.linalg.norm(_min_image(R - sites, box), axis=1)
    assert np.allclose(moved, 0.05 * A, atol=2e-3 * A)
    closest = [P.overlapping_pairs(X, A, box)[2].min() / (2 * A) for X in (R, c)]
    assert 0.95 < min(closest) and abs(closest[0] - closest[1]) < 0.01, closest


def test_lattice_acceptance_is_the_originals():
    """FCC is refused only when a lattice constant is below 2 sqrt(2) A (the original's
    exit: 256 spheres of A 2.83 in 32^3 have cells of 8 < 8.004); BCC is never refused
    (60 spheres of A 4 in 32^3 overlap at 0.866 of contact, and the original runs them)."""
    box = np.array([32.0, 32.0, 32.0])
    with pytest.raises(ValueError, match="FCC: the lattice constant along x is 8, below"):
        P.fcc(256, 2.83, box)
    assert len(P.fcc(256, 2.82, box, rng=0)) == 256
    R = P.bcc(60, 4.0, box)
    i, j, r = P.overlapping_pairs(R, 4.0, box)
    assert len(i) == 176 and np.isclose(r.min(), 8 * np.sqrt(3) / 2)
    assert "BCC left 176 pair(s) closer than the contact distance" in P.overlap_note(
        "BCC", R, 4.0, box)
    assert P.overlap_note("FCC", P.fcc_sites(100, box)[0], 2.0, box) is None
    with pytest.raises(ValueError, match="random_walk \\(its FCC start\\): the lattice"):
        P.random_walk(256, 2.83, box, 5, rng=0)


def test_bcc_in_a_non_cubic_box_stays_a_bcc_lattice():
    """The original shifts the odd layers by half the x cell in y too: in 64 x 32 x 32 the
    sites leave the box and the original aborts (an assertion in Particle_cell).  Here the
    shift is half the y cell: every site is in the box, the body centres at half a cell
    diagonal from the corners."""
    box = np.array([64.0, 32.0, 32.0])
    R = P.bcc(70, 2.0, box)
    assert np.all(R >= 0) and np.all(R < box)
    c = box / 4                                        # nn = ceil(35^(1/3)) = 4 cells
    i, j, dr = cells_pairs(R, box, 1.01 * c.max())
    r = np.linalg.norm(dr, axis=1)
    assert np.isclose(r.min(), min(c.min(), np.linalg.norm(c) / 2))
    centre = np.isclose(np.abs(dr), c / 2).all(axis=1)    # corner -> body centre
    assert centre.any()


def cells_pairs(R, box, rcut):
    from kapsel.particles.cells import pairs_within
    return pairs_within(R, box, rcut)


def test_random_walk():
    """The FCC start, then sweeps of a 0.025 A kick and a 0.05 A descent, nothing rejected
    (as the original): reproducible by seed, moving, and its spread is the original's (rms
    displacement from the sites after 100 sweeps of 100 spheres A 2 in 32^3: 0.499 in the
    original's run, 0.47-0.54 over seeds here)."""
    box = np.array([32.0, 32.0, 32.0])
    f = P.repulsion(box, 2.0)
    R = P.random_walk(100, 2.0, box, 100, rng=5, forces=f)
    assert np.array_equal(R, P.random_walk(100, 2.0, box, 100, rng=5, forces=f))
    sites, _ = P.fcc_sites(100, box)
    rms = [np.sqrt((_min_image(P.random_walk(100, 2.0, box, 100, rng=s, forces=f) - sites,
                               box) ** 2).sum(axis=1).mean()) for s in range(4)]
    assert 0.4 < min(rms) and max(rms) < 0.6, rms
    assert np.all(R >= 0) and np.all(R < box)


def test_each_descent_follows_its_own_force():
    """A descent moves a centre 0.05 A along the force at its present position.  (The
    original's random_walk adds every sweep's force to the previous sweeps' sum -- its force
    array is cleared once before the sweeps (init_particle.cxx) while the force routine adds
    to it (md_force.cxx) -- so a pair pushed apart keeps moving after its repulsion has
    ended.)  Two spheres 1.9 A apart: they separate 0.1 A per sweep until beyond the
    repulsion's range 2^(1/6) 2A, then stay."""
    box = np.array([32.0, 32.0, 32.0])
    A = 1.0
    R = np.array([[10.0, 10.0, 10.0], [11.9, 10.0, 10.0]])
    f = P.repulsion(box, A)
    gaps = []
    for _ in range(8):
        R = P.relax(R, A, box, np.random.default_rng(0), f, kick=0.0)
        gaps.append(R[1, 0] - R[0, 0])
    assert np.allclose(np.diff(gaps)[:2], 0.1)
    assert gaps[-1] == gaps[-2] and 2 ** (1 / 6) * 2 * A <= gaps[-1] < 2 ** (1 / 6) * 2 * A + 0.1


def test_orientations():
    rng = np.random.default_rng(0)
    q = P.orientations("random", 20000, rng)
    assert np.allclose(np.linalg.norm(q, axis=1), 1)
    # uniform rotations: rotated z axis uniform on the sphere (mean ~0, <z^2> = 1/3)
    z = Q.rotate(q, np.array([0, 0, 1.0]))
    assert np.abs(z.mean(axis=0)).max() < 0.03
    assert abs((z[:, 2] ** 2).mean() - 1 / 3) < 0.01
    assert np.array_equal(P.orientations("space_align", 3), Q.identity(3))
    assert np.array_equal(P.orientations("user_specify", 3), Q.identity(3))
    u = P.orientations("user_specify", 2, user_q=[[0, 0, 0, 0], [2, 0, 0, 2]])
    assert np.allclose(u, [[1, 0, 0, 0], [np.sqrt(0.5), 0, 0, np.sqrt(0.5)]])
    with pytest.raises(ValueError):
        P.orientations("sideways", 2)


@pytest.mark.parametrize("kind", ["FCC", "BCC", "random_walk"])
def test_lattices_between_walls(kind, tmp_path):
    """With flat walls the lattice fills the slab between them (the original builds it in
    the box shortened along the wall axis): 8 spheres of A 4 in ex14 (Z walls of 4 points,
    32^3) all in the fluid, clear of the walls' force."""
    import shutil
    from kapsel import cli
    from kapsel.models.common import make_particles
    from kapsel.particles.walls import clear_slab
    from udf import UDFManager
    src = os.path.join(TESTS, "..", "samples",
                       "kapsel-udf", "ex14")
    for f in os.listdir(src):
        shutil.copy(os.path.join(src, f), tmp_path / f)
    u = UDFManager(str(tmp_path / "input.udf"))
    u.put(8, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put(kind, "switch.INIT_distribution.type")
    u.put(3, "switch.INIT_distribution.random_walk.iteration")
    u.write(str(tmp_path / "input.udf"))
    cfg, _, _ = cli.validate(str(tmp_path / "input.udf"))
    p = make_particles(cfg, np.random.default_rng(0))
    axis, lo, hi = clear_slab(cfg)
    z = p.R[:, axis]
    assert p.n == 8 and axis == 2 and lo <= z.min() and z.max() < hi


def test_user_specify_deep_overlap_check_is_vectorised(tmp_path, monkeypatch):
    """user_specify positions closer than A (half the contact distance) are refused, naming
    the first such pair (lowest index, then its closest partner); 8000 particles are checked
    by a pair search, not a loop over particles."""
    import time
    from kapsel import cli
    from udf import UDFManager
    samples = os.path.join(TESTS, "..", "samples")
    copy_schema(tmp_path, samples)
    n, A = 8000, 2.0
    g = (np.arange(20) + 0.5) * 12.8                      # 20^3 sites, 12.8 apart in 256^3
    R = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    rows = np.zeros((n, 13))
    rows[:, 0:3] = R
    rows[:, 6] = 1.0
    rows[4321, 0:3] = R[17] + [1.5, 0, 0]                 # 1.5 < A from particle 17
    rows[5000, 0:3] = R[17] + [0, 1.9, 0]                 # and 1.9 from it
    u = UDFManager(os.path.join(samples, "input.udf"))
    u.put([8, 8, 8], "mesh")
    u.put(A, "A")
    u.put("user_specify", "switch.INIT_distribution.type")
    u.put(n, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put(rows, "switch.INIT_distribution.user_specify.Particles[]")
    u.write(str(tmp_path / "input.udf"))
    monkeypatch.setenv("KAPSEL_PY_MEMORY_LIMIT_GB", "1000")
    t0 = time.process_time()
    with pytest.raises(cli.BadInput, match="particles 17 and 4321 are 1.5 apart, less than "
                                           "half the contact distance 2A = 4"):
        cli.validate(str(tmp_path / "input.udf"))
    assert time.process_time() - t0 < 20
