"""Finite-difference operators on the periodic grid used by the MAC solver (manual §5.1).

Layout (semi-staggered Arakawa B grid): velocities at the nodes x = i*DX, pressure at the cell
centres x = (i+1/2)*DX; a cell array ``p[i, j, k]`` holds the value at (i+1/2, j+1/2, k+1/2).
Scalars have shape (NX, NY, NZ), vectors (3, NX, NY, NZ), indexed [x, y, z]; float64.

All operators are whole-array numpy: periodic shifts are done with slice copies into
caller-supplied ``out=`` / ``work=`` buffers (no ``np.roll`` temporaries, no loops over points).
``laplacian``, ``advection``, ``div_b`` and ``grad_b`` run as compiled single sweeps
(kapsel.mesh.stencils, bit-identical) on C-contiguous float64 arrays once kapsel.mesh.compiled
has loaded them.
``out`` must not alias the input.  Every operator but the original's non-conservative forms
(``advection_nc*``, ``viscous_variable_nc``) is a difference of periodic fluxes, so its sum
over the grid vanishes.

Fourier symbols are for ``numpy``/``pyfftw`` ``rfftn`` over the three grid axes of arrays in the
layout above (index Fourier convention, no cell-centre phase factor needed for the B-grid
div∘grad pair since it maps cell arrays to cell arrays).
"""
import numpy as np

from . import compiled as _c

__all__ = [
    "shift_assign", "shift_add", "shift_sub", "cdiff_acc",
    "laplacian", "grad_central", "div_central", "div_b", "grad_b",
    "advection", "advection_linear", "advection_nc", "advection_nc_linear",
    "symbol_inverse_laplacian", "viscous_variable_nc",
    "wavenumbers", "symbol_laplacian", "symbol_central", "symbol_div_grad_b",
    "b_grid_null_modes", "inverse_div_grad_b", "symbol_div_b", "symbol_grad_b",
]


# --------------------------------------------------------------------------- periodic shifts
def _sl(axis, start, stop):
    """Index tuple selecting start:stop along ``axis`` (negative: counted from the end)."""
    return (Ellipsis, slice(start, stop)) + (slice(None),) * (-axis - 1)


def _ix(axis, i):
    return (Ellipsis, i) + (slice(None),) * (-axis - 1)


def _ax(axis):
    """Grid axis 0,1,2 -> negative axis counted from the end (works for leading dims)."""
    return axis - 3 if axis >= 0 else axis


def shift_assign(out, f, s, axis):
    """out[i] = f[i+s] (periodic) along grid ``axis`` (0, 1, 2), s = +1 or -1."""
    a = _ax(axis)
    if s == 1:
        out[_sl(a, None, -1)] = f[_sl(a, 1, None)]
        out[_ix(a, -1)] = f[_ix(a, 0)]
    else:
        out[_sl(a, 1, None)] = f[_sl(a, None, -1)]
        out[_ix(a, 0)] = f[_ix(a, -1)]
    return out


def _shift_apply(op, out, f, s, axis):
    """out[i] = op(out[i], f[i+s]) (periodic), in place."""
    a = _ax(axis)
    if s == 1:
        o, g = out[_sl(a, None, -1)], f[_sl(a, 1, None)]
        op(o, g, out=o)
        o, g = out[_ix(a, -1)], f[_ix(a, 0)]
    else:
        o, g = out[_sl(a, 1, None)], f[_sl(a, None, -1)]
        op(o, g, out=o)
        o, g = out[_ix(a, 0)], f[_ix(a, -1)]
    op(o, g, out=o)
    return out


def shift_add(out, f, s, axis):
    """out[i] += f[i+s] (periodic)."""
    return _shift_apply(np.add, out, f, s, axis)


def shift_sub(out, f, s, axis):
    """out[i] -= f[i+s] (periodic)."""
    return _shift_apply(np.subtract, out, f, s, axis)


def _fdiff(out, f, axis):
    """out[i] = f[i+1] - f[i]."""
    shift_assign(out, f, 1, axis)
    np.subtract(out, f, out=out)
    return out


def _bdiff(out, f, axis):
    """out[i] = f[i] - f[i-1]."""
    shift_assign(out, f, -1, axis)
    np.subtract(f, out, out=out)
    return out


def cdiff_acc(out, f, axis):
    """out[i] += f[i+1] - f[i-1] (unscaled central difference, accumulated)."""
    shift_add(out, f, 1, axis)
    shift_sub(out, f, -1, axis)
    return out


_cdiff_acc = cdiff_acc


def _avg(out, f, s, axis):
    """out[i] = (f[i] + f[i+s]) / 2."""
    shift_assign(out, f, s, axis)
    np.add(out, f, out=out)
    out *= 0.5
    return out


def _buf(out, shape):
    return np.empty(shape) if out is None else out


def _compiled(*arrays):
    """True when the compiled kernels (kapsel.mesh.stencils, bit-identical to the numpy
    passes) take these arrays: float64, C-contiguous, 3 grid axes of at least 1 point."""
    return _c.stencils is not None and all(a.dtype == np.float64 and a.flags.c_contiguous
                                  for a in arrays)


# --------------------------------------------------------------------------- node operators
def laplacian(f, dx, out=None):
    """7-point node Laplacian of a scalar (NX,NY,NZ) or vector (3,NX,NY,NZ) field (eq 20)."""
    out = _buf(out, f.shape)
    if _compiled(f, out) and f.ndim in (3, 4):
        shp = (-1,) + f.shape[-3:]
        _c.stencils.laplacian(f.reshape(shp), 1.0 / (dx * dx), out.reshape(shp))
        return out
    np.multiply(f, -6.0, out=out)
    for ax in range(3):
        shift_add(out, f, 1, ax)
        shift_add(out, f, -1, ax)
    out *= 1.0 / (dx * dx)
    return out


def grad_central(f, dx, out=None):
    """Central gradient of a node scalar at the nodes -> (3, NX, NY, NZ)."""
    out = _buf(out, (3,) + f.shape)
    for ax in range(3):
        out[ax] = 0.0
        _cdiff_acc(out[ax], f, ax)
    out *= 0.5 / dx
    return out


def div_central(u, dx, out=None):
    """Central divergence of node velocities at the nodes."""
    out = _buf(out, u.shape[1:])
    out[...] = 0.0
    for ax in range(3):
        _cdiff_acc(out, u[ax], ax)
    out *= 0.5 / dx
    return out


# --------------------------------------------------------------------------- B-grid pair
def div_b(u, dx, out=None, work=None):
    """B-grid divergence: node velocity u -> cell centres (eq 21 left of the projection).

    (D u)_c = sum_a  (1/DX) * mean over the 4 cell edges along a of the node difference;
    done separably as  avg_b avg_c diff_a u_a.  ``work``: (2, NX, NY, NZ) scratch.
    """
    shp = u.shape[1:]
    out = _buf(out, shp)
    if _compiled(u, out) and u.ndim == 4:
        _c.stencils.div_b(u, 1.0 / dx, out)
        return out
    w = np.empty((2,) + shp) if work is None else work
    t0, t1 = w[0], w[1]
    # x: diff_x, avg_y, (avg_z later, shared with the y term)
    _fdiff(t0, u[0], 0)
    _avg(out, t0, 1, 1)
    # y: diff_y, avg_x
    _fdiff(t0, u[1], 1)
    _avg(t1, t0, 1, 0)
    np.add(out, t1, out=out)
    _avg(t0, out, 1, 2)                 # avg_z of (x + y terms)
    # z: diff_z, avg_x, avg_y
    _fdiff(out, u[2], 2)
    _avg(t1, out, 1, 0)
    _avg(out, t1, 1, 1)
    np.add(out, t0, out=out)
    out *= 1.0 / dx
    return out


def grad_b(p, dx, out=None, work=None):
    """B-grid gradient: cell-centre p -> nodes (the adjoint stencil, G = -D^T).

    (G p)_a at node n = (1/DX) * mean over the 4 cell pairs straddling n along a.
    ``work``: (2, NX, NY, NZ) scratch.
    """
    shp = p.shape
    out = _buf(out, (3,) + shp)
    if _compiled(p, out) and p.ndim == 3:
        _c.stencils.grad_b(p, 1.0 / dx, out)
        return out
    w = np.empty((2,) + shp) if work is None else work
    t0, t1 = w[0], w[1]
    # avg_z once, reused by x and y components
    _avg(t0, p, -1, 2)
    _bdiff(t1, t0, 0)
    _avg(out[0], t1, -1, 1)             # x: diff_x avg_y avg_z
    _bdiff(t1, t0, 1)
    _avg(out[1], t1, -1, 0)             # y: diff_y avg_x avg_z
    _avg(t0, p, -1, 0)
    _avg(t1, t0, -1, 1)
    _bdiff(out[2], t1, 2)               # z: diff_z avg_x avg_y
    out *= 1.0 / dx
    return out


# --------------------------------------------------------------------------- advection
def advection(u, dx, out=None, work=None):
    """Momentum-conserving advection in divergence form, div(u u)_i = sum_j D_j(u_j u_i),

    with central differences D_j at the nodes (eq 20's (u.grad)u for div u = 0).  Sums to
    zero over the periodic grid.  ``work``: (NX, NY, NZ) scratch.
    """
    shp = u.shape[1:]
    out = _buf(out, u.shape)
    if _compiled(u, out) and u.ndim == 4:
        _c.stencils.advection(u, 0.5 / dx, out)
        return out
    t = np.empty(shp) if work is None else work
    out[...] = 0.0
    for i in range(3):
        for j in range(i, 3):
            np.multiply(u[i], u[j], out=t)
            _cdiff_acc(out[i], t, j)
            if j != i:
                _cdiff_acc(out[j], t, i)
    out *= 0.5 / dx
    return out


def advection_nc(u, dx, out=None):
    """Advection in the original's non-conservative form (u.grad)u at the nodes, central
    differences: out_i = u_x D_x u_i + u_y D_y u_i + u_z D_z u_i, D_j f = (f[+e_j] -
    f[-e_j]) / (2 DX) (fdm.cxx U2advection, its order of operations)."""
    out = _buf(out, u.shape)
    if _compiled(u, out) and u.ndim == 4:
        _c.stencils.advection_nc(u, 1.0 / (2.0 * dx), out)
        return out
    return advection_nc_linear(u, u, dx, out)


def advection_nc_linear(a, w, dx, out=None):
    """(a.grad) w, non-conservative, central differences (fdm_matrix_solver.cxx
    NS_MAC_solver_implicit: u_s . grad w)."""
    out = _buf(out, w.shape)
    inv = 1.0 / (2.0 * dx)
    d = np.empty(w.shape[1:])
    t = np.empty(w.shape[1:])
    for i in range(3):
        for j in range(3):
            shift_assign(d, w[i], 1, j)
            shift_assign(t, w[i], -1, j)
            d -= t
            d *= inv
            if j == 0:
                np.multiply(a[0], d, out=out[i])
            else:
                d *= a[j]
                out[i] += d
    return out


def symbol_inverse_laplacian(shape, dx, block=None):
    """-1/|k|^2 (continuous wavenumbers k = 2 pi m / L), 0 at k = 0: the pressure Poisson
    solve of the original's FDM schemes (fdm.h Solve_poisson_dft)."""
    kx, ky, kz = wavenumbers(shape, dx, block)
    k2 = kx * kx + ky * ky + kz * kz
    inv = np.zeros(np.broadcast_shapes(kx.shape, ky.shape, kz.shape))
    np.divide(-1.0, k2, out=inv, where=k2 > 0)
    return inv


def advection_linear(a, w, dx, out=None, work=None):
    """Linearised divergence-form advection sum_j D_j(a_j w_i) (eq 23: u* . grad u^{n+1/2})."""
    shp = w.shape[1:]
    out = _buf(out, w.shape)
    t = np.empty(shp) if work is None else work
    out[...] = 0.0
    for i in range(3):
        for j in range(3):
            np.multiply(a[j], w[i], out=t)
            _cdiff_acc(out[i], t, j)
    out *= 0.5 / dx
    return out


# --------------------------------------------------------------------------- variable viscosity
def viscous_variable_nc(u, eta, dx, out=None, grad_eta=None, work=None):
    """The original's viscous term with the viscosity field eta at the nodes (eq 23 with
    viscosity_change; fdm_matrix_solver.cxx CHNS_MAC_solver_implicit_viscosity,
    fdm_phase_separation.cxx Set_poisson_rhs_viscosity): div(eta (grad u + grad u^T)) in
    the non-conservative form it takes for div u = 0,

        out_i = eta lap u_i + sum_j D_j eta (D_j u_i + D_i u_j),

    lap the 7-point Laplacian, D_j the central difference (f[+e_j] - f[-e_j]) / (2 DX).
    For uniform eta it is eta lap u exactly.  Not a difference of fluxes: its sum over the
    grid is not zero where eta varies.  ``grad_eta``: D eta (3, ...) (reused inside
    iterative solves); ``work``: (11, NX, NY, NZ) scratch (D u and two fields)."""
    shp = u.shape[1:]
    out = laplacian(u, dx, out)
    out *= eta
    g = grad_central(eta, dx) if grad_eta is None else grad_eta
    w = np.empty((11,) + shp) if work is None else work
    du = w[:9].reshape((3, 3) + shp)                 # du[i, j] = D_j u_i
    acc, t = w[9], w[10]
    for i in range(3):
        grad_central(u[i], dx, out=du[i])
    for i in range(3):
        np.multiply(g[i], du[i, i], out=acc)
        acc *= 2.0
        for j in range(3):
            if j != i:
                np.add(du[i, j], du[j, i], out=t)
                t *= g[j]
                acc += t
        out[i] += acc
    return out


# --------------------------------------------------------------------------- Fourier symbols
def wavenumbers(shape, dx, block=None):
    """Broadcastable (kx, ky, kz) in rad per length for rfftn over (NX, NY, NZ); ``block``:
    ((x0, x1), (y0, y1), (z0, z1)) of the half spectrum, the wavenumbers of that block only
    (a distributed run's Fourier block: the same values as the whole array's, cut)."""
    nx, ny, nz = shape
    k = [2 * np.pi * np.fft.fftfreq(nx, d=dx), 2 * np.pi * np.fft.fftfreq(ny, d=dx),
         2 * np.pi * np.fft.rfftfreq(nz, d=dx)]
    if block is not None:
        k = [q[a:b] for q, (a, b) in zip(k, block)]
    return k[0][:, None, None], k[1][None, :, None], k[2][None, None, :]


def symbol_laplacian(shape, dx, block=None):
    """Symbol of the 7-point Laplacian: -(4/DX^2) sum_a sin^2(k_a DX/2)."""
    s = 0.0
    for k in wavenumbers(shape, dx, block):
        s = s + np.sin(0.5 * k * dx) ** 2
    return -4.0 / dx ** 2 * s


def symbol_central(shape, dx):
    """Symbols (i sin(k_a DX)/DX) of the central first derivatives at the nodes."""
    return tuple(1j * np.sin(k * dx) / dx for k in wavenumbers(shape, dx))


def symbol_div_grad_b(shape, dx, block=None):
    """Symbol of the B-grid D∘G (cell -> cell):
    -(4/DX^2)[s_x^2 c_y^2 c_z^2 + c_x^2 s_y^2 c_z^2 + c_x^2 c_y^2 s_z^2],
    s_a = sin(k_a DX/2), c_a = cos(k_a DX/2).  Zero at the null modes (b_grid_null_modes)."""
    kx, ky, kz = wavenumbers(shape, dx, block)
    sx, sy, sz = (np.sin(0.5 * k * dx) ** 2 for k in (kx, ky, kz))
    cx, cy, cz = 1 - sx, 1 - sy, 1 - sz
    return -4.0 / dx ** 2 * (sx * cy * cz + cx * sy * cz + cx * cy * sz)


def b_grid_null_modes(shape, block=None):
    """Boolean rfftn-shaped mask of the null space of G (and of D∘G): k = 0 and, for even N,
    every mode with at least two of (k_x, k_y, k_z) at the Nyquist value pi/DX (the B-grid
    checkerboard pressure modes, e.g. p ~ (-1)^(i+j) for any k_z)."""
    nx, ny, nz = shape
    if block is None:
        block = ((0, nx), (0, ny), (0, nz // 2 + 1))
    ix = np.arange(*block[0])[:, None, None]
    iy = np.arange(*block[1])[None, :, None]
    iz = np.arange(*block[2])[None, None, :]
    qx = (nx % 2 == 0) & (ix == nx // 2)
    qy = (ny % 2 == 0) & (iy == ny // 2)
    qz = (nz % 2 == 0) & (iz == nz // 2)
    n = qx.astype(int) + qy.astype(int) + qz.astype(int)
    zero = (ix == 0) & (iy == 0) & (iz == 0)
    return np.broadcast_to((n >= 2) | zero, tuple(b - a for a, b in block)).copy()


def inverse_div_grad_b(shape, dx, block=None):
    """1 / symbol_div_grad_b, set to 0 on the null modes.

    Choosing zero pressure there is a gauge choice: D u has no component on these modes (the
    symbol of D vanishes there too) and G annihilates them, so the projected velocity is the
    same for any value.  The result is used to solve D G phi = D u by FFT."""
    s = symbol_div_grad_b(shape, dx, block)
    mask = b_grid_null_modes(shape, block)
    s = np.where(mask, 1.0, s)
    inv = 1.0 / s
    inv[mask] = 0.0
    return inv


def symbol_div_b(shape, dx, block=None):
    """Symbols (per component) of div_b (node array -> cell array, index convention):
    (e^{i k_a DX} - 1)/DX * prod_{b != a} (1 + e^{i k_b DX})/2."""
    k = wavenumbers(shape, dx, block)
    e = [np.exp(1j * q * dx) for q in k]
    h = [(1 + q) / 2 for q in e]
    return ((e[0] - 1) / dx * h[1] * h[2], (e[1] - 1) / dx * h[0] * h[2],
            (e[2] - 1) / dx * h[0] * h[1])


def symbol_grad_b(shape, dx):
    """Symbols of grad_b (cell array -> node array): the adjoint, -conj(symbol_div_b)."""
    return tuple(-np.conj(s) for s in symbol_div_b(shape, dx))
