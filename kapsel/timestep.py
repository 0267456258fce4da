"""The automatic time step of KAPSEL (manual §5.5)."""
import math


def auto_dt(factor: float, rho: float, eta: float, dx: float) -> float:
    """dt = factor * T_dump, T_dump = RHO / (ETA k_max^2), k_max = pi / DX.

    k_max is the Nyquist wavenumber, the largest the grid resolves; with it the explicit
    finite-difference diffusion of the MAC scheme is stable (nu dt / DX^2 = 1/pi^2 < 1/6).
    """
    k_max = math.pi / dx
    return factor * rho / (eta * k_max ** 2)
