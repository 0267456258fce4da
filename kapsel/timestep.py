"""The automatic time step of KAPSEL (manual §5.5, FORMAT.md)."""
import math


def kmax2(dx: float, shape) -> float:
    """KMAX2 = sum over x, y, z of (2 pi TRN_d / L_d)^2, L_d = N_d DX, TRN_d = floor((N_d + 2)
    / 3): the squared wavenumber of the corner of the 2/3-truncated cube of modes."""
    total = 0.0
    for n in shape:
        trn = (int(n) + 2) // 3
        total += (2.0 * math.pi * trn / (int(n) * dx)) ** 2
    return total


def auto_dt(factor: float, rho: float, eta: float, dx: float, shape) -> float:
    """dt = factor / (NU KMAX2), NU = ETA / RHO: the original's formula (FORMAT.md;
    0.0714552 x factor for a 32^3 mesh with DX = RHO = ETA = 1).

    With it nu dt / DX^2 <= 1 / (3 (2 pi / 3)^2) ~ 0.076 < 1/6, so the explicit
    finite-difference diffusion of the MAC scheme is stable too."""
    return factor * rho / (eta * kmax2(dx, shape))


def electrolyte_dt(factor: float, rho: float, eta: float, kBT: float, onsager_max: float,
                   dx: float, shape, frequency: float = 0.0) -> float:
    """Electrolyte (PHYSICS-EXTRA §6.5): dt = factor T_dump, T_dump = min(1 / (NU KMAX2),
    1 / (kBT L_max KMAX2)) (L_max the largest Onsager coefficient: the explicit ion
    diffusion's limit), and with an AC field (frequency f > 0) T_dump <= 0.01 / f."""
    k2 = kmax2(dx, shape)
    t = rho / (eta * k2)
    if kBT * onsager_max > 0:
        t = min(t, 1.0 / (kBT * onsager_max * k2))
    if frequency > 0:
        t = min(t, 0.01 / frequency)
    return factor * t
