"""LJ_powers "electro_osmotic_flow" and the sheared types' LJ diameter
(kapsel.particles.forces; PHYSICS-EXTRA.md §5)."""
import math
import types

import numpy as np
import pytest

from kapsel.particles import forces as pf

EOF = "electro_osmotic_flow"


def g_original(r, sigma, eps):
    """§5's g(r) (force = g r) of the tail, r >= 1.01 sigma."""
    return -eps * math.exp(-r / (3 * sigma)) * (r / (3 * sigma) + 2) / r ** 3


@pytest.mark.parametrize("truncate", ["OFF", "ON"])
def test_eof_force_is_minus_the_derivative_of_its_potential(truncate):
    sigma, eps = 8.0, 2.5
    rs = np.concatenate([np.linspace(0.9, 1.0, 5), np.linspace(1.02, 2.45, 20)]) * sigma
    h = 1e-6
    for r in rs:
        F = float(pf.pair_force_magnitude(r, sigma, EOF, eps, truncate))
        dV = (pf.pair_potential(r + h, sigma, EOF, eps, truncate)
              - pf.pair_potential(r - h, sigma, EOF, eps, truncate)) / (2 * h)
        if truncate == "ON" and r >= sigma:
            assert F == 0.0 and pf.pair_potential(r, sigma, EOF, eps, truncate) == 0.0
            continue
        assert -float(dV) == pytest.approx(F, rel=1e-6, abs=1e-10)
        if r >= 1.01 * sigma:
            assert F == pytest.approx(g_original(r, sigma, eps) * r, rel=1e-12)
            assert F < 0                                   # attractive tail
        else:
            s = (sigma / r) ** 18
            assert F == pytest.approx(72 * eps * (2 * s * s - s) / r, rel=1e-12)
    # the energy is continuous where the force jumps (1.01 sigma), 0 at the cut for ON
    if truncate == "OFF":
        a, b = (pf.pair_potential(x * sigma, sigma, EOF, eps, "OFF") for x in (1.01 - 1e-9,
                                                                               1.01 + 1e-9))
        assert a == pytest.approx(b, abs=1e-7)
        assert pf.interaction_range(EOF, "OFF") == pf.LJ_CUTOFF_OFF
    else:
        assert pf.pair_potential(sigma * (1 - 1e-9), sigma, EOF, eps, "ON") == \
            pytest.approx(0.0, abs=1e-6)
        assert pf.interaction_range(EOF, "ON") == 1.0


def test_eof_pair_forces_are_minus_the_gradient_of_the_energy():
    rng = np.random.default_rng(3)
    box = np.array([60.0, 60.0, 60.0])
    A = 4.0
    R = np.array([[10.0, 10, 10], [19.0, 11, 10], [12, 22, 13], [30, 30, 30], [38.5, 31, 30]])
    R += rng.uniform(-0.2, 0.2, R.shape)
    F, U, _ = pf.pair_forces(R, box, A, EOF, 1.5, "OFF")
    assert np.allclose(F.sum(axis=0), 0.0, atol=1e-12)
    h = 1e-6
    for i in range(len(R)):
        for c in range(3):
            up, dn = R.copy(), R.copy()
            up[i, c] += h
            dn[i, c] -= h
            dU = (pf.pair_forces(up, box, A, EOF, 1.5, "OFF")[1]
                  - pf.pair_forces(dn, box, A, EOF, 1.5, "OFF")[1]) / (2 * h)
            assert -dU == pytest.approx(F[i, c], rel=1e-5, abs=1e-9)


def test_sheared_lj_diameter():
    """LJ_dia = min((2a + XI)/c, 2a): the 2n:n minimum c LJ_dia at most a gap XI out."""
    assert pf.sheared_lj_dia("12:6", 4.0, 2.0) == 8.0
    assert pf.sheared_lj_dia("12:6", 4.0, 0.5) == pytest.approx(8.5 / 2 ** (1 / 6))
    assert pf.sheared_lj_dia("36:18", 4.0, 0.2) == pytest.approx(8.2 / 2 ** (1 / 18))
    assert pf.sheared_lj_dia("macro_vdw", 4.0, 0.2) == 8.0
    assert pf.sheared_lj_dia(EOF, 4.0, 0.2) == 8.0


@pytest.mark.parametrize("eq,sigma", [("Shear_Navier_Stokes_Lees_Edwards", 8.5 / 2 ** (1 / 6)),
                                      ("Navier_Stokes", 8.0)])
def test_sheared_types_use_their_lj_diameter(eq, sigma):
    from kapsel.models.common import make_forces
    from kapsel.particles.state import ParticleState
    inter = types.SimpleNamespace(LJ_truncate="ON", EPSILON=1.0, LJ_powers="12:6", G=0.0,
                                  G_direction="-Z")
    cfg = types.SimpleNamespace(type=eq, interactions=inter,
                                mesh=types.SimpleNamespace(box=np.array([32.0] * 3)),
                                particles=types.SimpleNamespace(object_type="spherical_particle",
                                                                A=4.0, A_XI=0.5),
                                switches=types.SimpleNamespace(wall=None))
    p = ParticleState.spheres([0, 0], [4.0, 4.0], [1.0, 1.0], 1.0)
    p.R[:] = [[10.0, 10, 10], [17.8, 10, 10]]
    F = make_forces(cfg, p)(p)[0]
    assert F[1, 0] == pytest.approx(pf.pair_force_magnitude(7.8, sigma, "12:6", 1.0, "ON"))
    assert F[1, 0] > 0
