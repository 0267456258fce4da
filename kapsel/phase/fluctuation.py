"""The initial composition of the two-component fluid, drawn as the original draws it.

The original (fdm_phase_separation.cxx: Init_phase_separation) draws one number per node,
x fastest-varying last (its i, j, k loops: the C order of our (NX, NY, NZ) arrays), from a
32-bit Mersenne Twister seeded with the fixed 12345 (whatever the input's seed), uniform in
[composition_ratio - initial_fluctuation, composition_ratio + initial_fluctuation).  Each
number takes two 32-bit words g1, g2 (the C++ library's canonical draw of a double):
u = (g1 + g2 2^32) / 2^64 (held below 1), value = lo + u (hi - lo).  Done here with numpy's
MT19937 under its legacy (init_genrand) seeding, the same words in the same order, so the
field is bit-identical to the original's.

The particles' share: psi = value (1 - phi) for Landau, value (1 - phi) + phi psi_n for
Flory-Huggins (psi_n = 0.5 there), with phi the particle profile at the start.
"""
import numpy as np

__all__ = ["ORIGINAL_SEED", "original_uniform", "initial_composition"]

ORIGINAL_SEED = 12345


def original_uniform(n, lo, hi, seed=ORIGINAL_SEED):
    """n doubles uniform in [lo, hi), the original's generator and draw (module docstring)."""
    bits = np.random.MT19937(0)
    bits._legacy_seeding(int(seed))
    words = bits.random_raw(2 * int(n)).astype(np.float64).reshape(-1, 2)
    u = words[:, 0] + words[:, 1] * 4294967296.0          # one rounding, as the C++ sum
    u *= 2.0 ** -64
    np.minimum(u, np.nextafter(1.0, 0.0), out=u)
    u *= (hi - lo)
    u += lo
    return u


def initial_composition(shape, params):
    """The original's draw on a mesh of ``shape``, before the particles' share (module
    docstring): params are a kapsel.config.PhaseField (composition_ratio,
    initial_fluctuation)."""
    ratio, fluct = float(params.composition_ratio), float(params.initial_fluctuation)
    return original_uniform(int(np.prod(shape)), ratio - fluct, ratio + fluct).reshape(shape)
