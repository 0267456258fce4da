"""Bead-spring chains (kapsel.particles.chains): FENE bonds, placement, runs.

Measured: two chains of 6 beads (A = 4, xi = 2, EPSILON = 1, WCA 12:6), spectral L = 32,
kBT = 1, auto_dt(1): over 500 steps every bond stayed within 0.933 .. 1.016 sigma (rest
length 0.961 sigma); the documented tolerance is 0.9 .. 1.1 sigma for kBT <= EPSILON.
"""
import os
import subprocess
import sys
import types

import numpy as np
import pytest

from kapsel import config
from kapsel.particles import chains
from kapsel.particles.forces import pair_forces
from udf import UDFManager

from builders import chain_input, TESTS


SAMPLES = os.path.join(TESTS, "..", "samples")
A = 4.0
BOX = np.array([32.0, 32.0, 32.0])


def test_bonds_join_consecutive_beads_of_each_chain():
    i, j = chains.chain_bonds([3, 1, 2])
    assert list(i) == [0, 1, 4] and list(j) == [1, 2, 5]
    assert len(chains.chain_bonds([1, 1])[0]) == 0


def test_fene_force_is_minus_the_gradient_and_balances():
    R = np.array([[1.0, 2.0, 3.0], [8.5, 3.0, 2.0], [14.0, 7.0, 4.0]])
    i, j = chains.chain_bonds([3])
    F, stretch = chains.fene_forces(R, BOX, A, i, j, 2.0)
    assert np.allclose(F.sum(axis=0), 0.0, atol=1e-12)

    def energy(X):
        r = chains.bond_lengths(X, BOX, i, j)
        return chains.fene_energy(r, 2 * A, 2.0).sum()
    h = 1e-6
    for k in range(3):
        for a in range(3):
            d = np.zeros_like(R)
            d[k, a] = h
            assert F[k, a] == pytest.approx(-(energy(R + d) - energy(R - d)) / (2 * h),
                                            rel=1e-6, abs=1e-9)
    r = chains.bond_lengths(R, BOX, i, j)
    assert stretch == pytest.approx(r.max() / (1.5 * 2 * A))
    # the constants: K = 30 EPSILON / sigma^2, R0 = 1.5 sigma
    f, _ = chains.fene_forces(np.array([[0.0, 0, 0], [4.0, 0, 0]]), BOX, A, [0], [1], 1.0)
    assert f[1, 0] == pytest.approx(-30 / 64 * 4 / (1 - (4 / 12) ** 2))


def test_rest_length_with_wca_is_0961_sigma():
    from scipy.optimize import brentq

    def net(r):
        R = np.array([[0.0, 0, 0], [r, 0, 0]])
        F = pair_forces(R, [64.0] * 3, [A, A], "12:6", 1.0, "ON")[0]
        return F[1, 0] + chains.fene_forces(R, [64.0] * 3, A, [0], [1], 1.0)[0][1, 0]
    assert brentq(net, 7.0, 8.9) / (2 * A) == pytest.approx(0.961, abs=5e-4)


def test_random_walk_chains_are_bonded_and_do_not_overlap():
    from kapsel.particles.placement import overlapping_pairs
    rng = np.random.default_rng(3)
    R = chains.random_walk_chains([5, 5, 4], A, BOX, rng)
    i, j = chains.chain_bonds([5, 5, 4])
    assert np.allclose(chains.bond_lengths(R, BOX, i, j), 2 * A)
    assert np.all((R >= 0) & (R < BOX))
    assert len(overlapping_pairs(R, 0.999 * A, BOX)[0]) == 0
    with pytest.raises(ValueError, match="too crowded"):
        chains.random_walk_chains([40] * 3, A, BOX, rng, attempts=3)


def test_thermal_chains_keep_their_bond_lengths(tmp_path):
    from kapsel.models.spectral import SpectralModel
    cfg = config.load(chain_input(tmp_path, constitutive_eq__Navier_Stokes__kBT=1.0))
    m = SpectralModel(cfg, types.SimpleNamespace(seed=2, quiet=True, threads=1))
    i, j = chains.chain_bonds([6, 6])
    lo, hi = np.inf, 0.0
    R0 = m.particles.R.copy()
    for _ in range(300):
        m.advance()
        b = chains.bond_lengths(m.particles.R, cfg.mesh.box, i, j) / (2 * A)
        lo, hi = min(lo, b.min()), max(hi, b.max())
    assert 0.9 < lo and hi < 1.1
    assert np.abs(m.particles.R_raw - R0).max() > 0.5            # the beads did move


def test_a_bond_stretched_to_r0_stops_the_run(tmp_path):
    from kapsel.models.common import make_forces, make_particles
    cfg = config.load(chain_input(tmp_path))
    p = make_particles(cfg, np.random.default_rng(0))
    forces = make_forces(cfg, p)
    forces(p)
    p.R[1] = p.R[0] + [0.0, 0.0, 11.95]                          # R0 = 12
    with pytest.raises(FloatingPointError, match="chain bond stretched"):
        forces(p)


def test_pinned_chain_bead_stays(tmp_path):
    from kapsel.models.spectral import SpectralModel
    cfg = config.load(chain_input(tmp_path, constitutive_eq__Navier_Stokes__kBT=1.0,
                                  switch__pin__type="YES"))          # the sample pins 2
    m = SpectralModel(cfg, types.SimpleNamespace(seed=2, quiet=True, threads=1))
    R = m.particles.R.copy()
    for _ in range(50):
        m.advance()
    # held: only the original's periodic wrap fmod(x + L, L) rounds it (once, to the ulp of L)
    assert np.abs(m.particles.R[2] - R[2]).max() <= 4e-15 * m.particles.R.max()
    assert np.array_equal(m.particles.R_raw[2], R[2])
    assert np.abs(m.particles.R - R).max() > 0.1


@pytest.mark.parametrize("puts, path", [
    (dict(EPSILON=0.0), "EPSILON"),
    (dict(switch__LJ_truncate="NONE"), "switch.LJ_truncate"),
    (dict(switch__INIT_distribution__type="BCC"), "switch.INIT_distribution.type"),
])
def test_unsupported_chain_options_are_named(tmp_path, puts, path):
    with pytest.raises(config.ConfigError, match=path):
        config.load(chain_input(tmp_path, **puts))


def test_janus_axis_of_chains_is_accepted(tmp_path):
    """The original reads a chain's janus_axis but forces its propulsion OFF
    (PHYSICS-EXTRA §1.2): an axis alone propels nothing, so the input runs."""
    path = chain_input(tmp_path)
    u = UDFManager(path)
    u.put("Z", "object_type.chain.Chain_spec[0].janus_axis")
    u.write(path)
    assert config.load(path).particles.object_type == "chain"


@pytest.mark.parametrize("eq", ["Navier_Stokes", "Navier_Stokes_FDM"])
def test_kapsel_py_runs_chains(tmp_path, eq):
    chain_input(tmp_path, specs=((4, 2), (3, 1)), eq=eq, output__GTS=10, output__Num_snap=2,
                **{f"constitutive_eq__{eq}__kBT": 0.5})
    r = subprocess.run([sys.executable, "-m", "kapsel.cli", "-Ichain.udf", "-Oout.udf",
                        "-Ddefine.udf", "-Rrestart.udf", "--seed", "3", "--quiet"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    u = UDFManager(str(tmp_path / "out.udf"))
    assert u.totalRecord() == 3
    i, j = chains.chain_bonds([4, 4, 3])
    for n in range(3):
        u.jump(n)
        assert u.size("Particles[]") == 11 and u.size("RigidParticles[]") == 0
        b = chains.bond_lengths(np.array(u.getArray("Particles[].R")), BOX, i, j) / (2 * A)
        assert np.all((b > 0.9) & (b < 1.1))


def test_user_specified_chains_need_bonds_shorter_than_r0(tmp_path):
    from kapsel.models.common import make_particles
    X = [[4.0, 4, 4], [12.0, 4, 4], [12.0, 12, 4], [20.0, 12, 4], [20.0, 20, 4], [20.0, 20, 12],
         [4.0, 20, 20], [12.0, 20, 20], [12.0, 28, 20], [20.0, 28, 20], [20.0, 28, 28],
         [28.0, 28, 28]]
    parts = np.array([x + [0.0, 0, 0, 1, 0, 0, 0, 0, 0, 0] for x in X])
    path = chain_input(tmp_path, switch__INIT_distribution__type="user_specify")
    u = UDFManager(path)
    u.put(parts, "switch.INIT_distribution.user_specify.Particles[]")
    u.write(path)
    p = make_particles(config.load(path), np.random.default_rng(0))
    assert np.allclose(p.R, X)
    parts[7, :3] = [16.0, 20, 20]                                # bond 6-7 of length 12
    u.put(parts, "switch.INIT_distribution.user_specify.Particles[]")
    u.write(path)
    with pytest.raises(config.ConfigError, match="beads 6 and 7 is 12 long"):
        make_particles(config.load(path), np.random.default_rng(0))
