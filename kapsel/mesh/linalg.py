"""The iterative solver shared by the implicit schemes (manual §5.1 eqs 23-26, §5.3 eq 31):
BiCGSTAB, unpreconditioned as in the original unless a preconditioner is given."""
from __future__ import annotations

import numpy as np
from scipy.sparse.linalg import LinearOperator, bicgstab

from ..errors import SolverDidNotConverge


def solve_correction(A, b, x0, tolerance, maximum_iteration, M=None, what="BiCGSTAB",
                     dot=None):
    """Solve A x = b to ||b - A x|| <= tolerance ||b|| starting from x0.

    BiCGSTAB runs on the correction d = x - x0, normalised to a unit residual so scipy's
    breakdown thresholds are scale-free.  Returns (x, iterations, residual); residual is NaN
    when converged (not recomputed: it would cost a matrix-vector product).  Raises
    SolverDidNotConverge otherwise.  ``dot((a, b), ...)``: the dot products of a distributed
    run (vectors are this rank's blocks, summed over the ranks; ``bicgstab_dot`` below),
    None: one process, scipy's BiCGSTAB."""
    norm = np.linalg.norm if dot is None else (lambda v: np.sqrt(dot((v, v))[0]))
    bn = float(norm(b))
    if bn == 0.0:
        return np.zeros_like(b), 0, 0.0
    r0 = b - A @ x0
    rn = float(norm(r0))
    if rn <= tolerance * bn:
        return x0, 0, rn / bn
    nmv = [0]

    def mv(v):
        nmv[0] += 1
        return A @ v
    r0 /= rn
    if dot is None:
        d, info = bicgstab(LinearOperator(A.shape, matvec=mv, dtype=np.float64), r0,
                           rtol=tolerance * bn / rn, atol=0.0, maxiter=maximum_iteration, M=M)
    else:
        d, info = bicgstab_dot(mv, r0, tolerance * bn / rn, maximum_iteration, dot,
                               None if M is None else M.matvec)
    d *= rn
    x = x0 + d
    iterations = (nmv[0] + 1) // 2     # 2 matvecs per BiCGSTAB iteration
    if info == 0:
        return x, iterations, float("nan")
    res = float(norm(b - A @ x)) / bn
    if not res <= tolerance:
        raise SolverDidNotConverge(iterations, res, what=what)
    return x, iterations, res


def bicgstab_dot(matvec, b, atol, maxiter, dots, psolve=None):
    """scipy.sparse.linalg.bicgstab's iteration (x0 = 0, the same breakdown tests and
    order of updates) with the dot products ``dots((a, b), ...) -> [a.b, ...]``: the
    BiCGSTAB of a distributed run, whose vectors are the ranks' blocks and whose dot
    products are summed over the ranks in a fixed order (the same bits on every rank, so
    every rank takes the same branch).  The products needed at one point of the iteration
    are summed in one collective (4 per iteration instead of scipy's 6 reductions): every
    collective is a synchronisation of the ranks.  Returns (x, info) as scipy: 0
    converged, > 0 not within maxiter, < 0 breakdown."""
    psolve = (lambda v: v.copy()) if psolve is None else psolve
    rhotol = np.finfo(np.float64).eps ** 2
    omegatol = rhotol
    x = np.zeros_like(b)
    r = b.copy()
    rtilde = r.copy()
    rho_prev = omega = alpha = p = v = s = None
    for iteration in range(maxiter):
        rr, rho = dots((r, r), (rtilde, r))
        if np.sqrt(rr) < atol:
            return x, 0
        if abs(rho) < rhotol:
            return x, -10
        if iteration > 0:
            if abs(omega) < omegatol:
                return x, -11
            beta = (rho / rho_prev) * (alpha / omega)
            p -= omega * v
            p *= beta
            p += r
        else:
            s = np.empty_like(r)
            p = r.copy()
        phat = psolve(p)
        v = matvec(phat)
        rv = dots((rtilde, v))[0]
        if rv == 0:
            return x, -11
        alpha = rho / rv
        r -= alpha * v
        s[:] = r[:]
        if np.sqrt(dots((s, s))[0]) < atol:
            x += alpha * phat
            return x, 0
        shat = psolve(s)
        t = matvec(shat)
        ts, tt = dots((t, s), (t, t))
        omega = ts / tt
        x += alpha * phat
        x += omega * shat
        r -= omega * t
        rho_prev = rho
    return x, maxiter
