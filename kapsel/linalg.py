"""The iterative solver shared by the implicit schemes (manual §5.1 eqs 23-26, §5.3 eq 31):
BiCGSTAB, unpreconditioned as in the original unless a preconditioner is given."""
from __future__ import annotations

import numpy as np
from scipy.sparse.linalg import LinearOperator, bicgstab


class SolverDidNotConverge(RuntimeError):
    """BiCGSTAB did not reach ``tolerance`` within ``maximum_iteration`` (manual table 2)."""

    def __init__(self, iterations, residual, message=None, what="BiCGSTAB"):
        self.iterations = int(iterations)
        self.residual = float(residual)
        super().__init__(message or (
            "%s did not converge in %d iterations: relative residual %.3e; reduce the time "
            "step or raise maximum_iteration" % (what, self.iterations, self.residual)))


class UnstableTimeStep(ValueError):
    """dt above an explicit scheme's stability limit."""


def solve_correction(A, b, x0, tolerance, maximum_iteration, M=None, what="BiCGSTAB"):
    """Solve A x = b to ||b - A x|| <= tolerance ||b|| starting from x0.

    BiCGSTAB runs on the correction d = x - x0, normalised to a unit residual so scipy's
    breakdown thresholds are scale-free.  Returns (x, iterations, residual); residual is NaN
    when converged (not recomputed: it would cost a matrix-vector product).  Raises
    SolverDidNotConverge otherwise."""
    bn = float(np.linalg.norm(b))
    if bn == 0.0:
        return np.zeros_like(b), 0, 0.0
    r0 = b - A @ x0
    rn = float(np.linalg.norm(r0))
    if rn <= tolerance * bn:
        return x0, 0, rn / bn
    nmv = [0]

    def mv(v):
        nmv[0] += 1
        return A @ v
    r0 /= rn
    d, info = bicgstab(LinearOperator(A.shape, matvec=mv, dtype=np.float64), r0,
                       rtol=tolerance * bn / rn, atol=0.0, maxiter=maximum_iteration, M=M)
    d *= rn
    x = x0 + d
    iterations = (nmv[0] + 1) // 2     # 2 matvecs per BiCGSTAB iteration
    if info == 0:
        return x, iterations, float("nan")
    res = float(np.linalg.norm(b - A @ x)) / bn
    if not res <= tolerance:
        raise SolverDidNotConverge(iterations, res, what=what)
    return x, iterations, res
