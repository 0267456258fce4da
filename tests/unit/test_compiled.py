"""The compiled kernels (kapsel.mesh.compiled) change no bit of a run: a run that switches to them
mid-way (as the time loop does at step 10) ends in the same state as one on numpy passes."""
import numpy as np
import pytest

from kapsel import config
from kapsel.mesh import compiled
from kapsel.typespec import SOLVERS
from udf import UDFManager

from builders import Args, electrolyte_input, fdm_sample, janus_input


def _run(path, kernels, switch_at, steps=4):
    """The state after ``steps`` steps on numpy passes, the compiled kernels switched on
    (``kernels``: the compiled_kernels fixture) before step ``switch_at``."""
    import kapsel.models  # noqa: F401  (registers the types)
    doc = UDFManager(path)
    cfg = config.from_document(doc, path)
    kernels.off()
    m = SOLVERS[cfg.type](cfg, Args(), doc)
    for k in range(steps):
        if k == switch_at:
            kernels.on()
        m.advance()
    state = [m.velocity_field().copy(), m.particles.R.copy(), m.particles.omega.copy()]
    if getattr(m, "psi", None) is not None:
        state.append(m.psi.copy())
    if getattr(m, "ions", None) is not None:            # the ion densities and their field
        m.ions.potential()
        state += [m.ions.c.copy(), m.ions.grad_psi.copy()]
    kernels.off()
    return state


@pytest.mark.parametrize("eq,ns", [("Navier_Stokes", "explicit_scheme"),
                                   ("Navier_Stokes_FDM", "implicit_scheme"),
                                   ("Navier_Stokes_Cahn_Hilliard_FDM", "explicit_scheme"),
                                   ("Shear_Navier_Stokes_Lees_Edwards", "explicit_scheme"),
                                   ("Shear_Navier_Stokes", "explicit_scheme")])
def test_switching_to_compiled_kernels_is_bit_identical(tmp_path, eq, ns, compiled_kernels):
    path = fdm_sample(tmp_path, eq=eq, ns=ns)
    a = _run(path, compiled_kernels, switch_at=None)
    b = _run(path, compiled_kernels, switch_at=2)
    for x, y in zip(a, b):
        assert np.array_equal(x, y)


@pytest.mark.parametrize("salt,field", [(True, "DC"), (False, "OFF")])
def test_switching_electrolyte_to_compiled_kernels_is_bit_identical(tmp_path, salt, field,
                                                                   compiled_kernels):
    """The Electrolyte fluid step projects the nonlinear term once on either path (the numpy
    path used to project it twice: a run's bits depended on when the kernels loaded)."""
    path = electrolyte_input(str(tmp_path), salt=salt, field=field)
    a = _run(path, compiled_kernels, switch_at=None)
    b = _run(path, compiled_kernels, switch_at=2)
    for x, y in zip(a, b):
        assert np.array_equal(x, y)


@pytest.mark.parametrize("eq", ["Navier_Stokes", "Shear_Navier_Stokes"])
def test_switching_squirmers_to_compiled_kernels_is_bit_identical(tmp_path, eq,
                                                                 compiled_kernels):
    """Squirmers (pushers), a tumbler and an obstacle: the slip step's stencil
    sums, slip field and slip forces give the numpy forms' bits (kapsel.particles.janus)."""
    path = janus_input(tmp_path, eq=eq)
    a = _run(path, compiled_kernels, switch_at=None)
    b = _run(path, compiled_kernels, switch_at=2)
    for x, y in zip(a, b):
        assert np.array_equal(x, y)


def test_want_policy(monkeypatch):
    monkeypatch.setenv("KAPSEL_PY_COMPILED", "auto")
    assert not compiled.want(compiled.AFTER_STEPS - 1, 1000)
    assert not compiled.want(compiled.AFTER_STEPS, compiled.MIN_REMAINING - 1)
    assert compiled.want(compiled.AFTER_STEPS, compiled.MIN_REMAINING)
    # with the mesh: only when the steps left repay the loading
    assert not compiled.want(compiled.AFTER_STEPS, 190, points=32 ** 3)    # 32^3, 200 steps
    assert compiled.want(compiled.AFTER_STEPS, 190, points=64 ** 3)        # 64^3, 200 steps
    assert compiled.want(compiled.AFTER_STEPS, 990, points=32 ** 3)        # 32^3, 1000 steps
    pays = compiled.LOAD_CPU / compiled.SAVING_PER_POINT                   # steps x points
    assert compiled.want(compiled.AFTER_STEPS, 1000, points=int(1.001 * pays / 1000))
    assert not compiled.want(compiled.AFTER_STEPS, 1000, points=int(0.999 * pays / 1000))
    monkeypatch.setenv("KAPSEL_PY_COMPILED", "0")
    assert not compiled.want(10 ** 6, 10 ** 6) and not compiled.enable()
    monkeypatch.setenv("KAPSEL_PY_COMPILED", "1")
    assert compiled.want(0, 0)


def test_ahead_of_time_kernels_check_their_arguments(compiled_kernels):
    """The ahead-of-time machine code trusts its arguments: its wrapper sends a call that
    does not fit the recorded types (a strided view, another dtype, a float for an int) to
    the JIT kernel, which gives the same numbers (or numba's typing error), instead of
    reading the wrong memory."""
    if compiled_kernels.kind != "aot":
        pytest.skip("the wrapper of the ahead-of-time build")
    import kapsel.fluid.spectral  # noqa: F401  (provides the spectral slot)
    compiled_kernels.on()
    K = compiled.spectral
    rng = np.random.default_rng(2)
    u_hat = rng.standard_normal((3, 6, 8, 5)) + 1j * rng.standard_normal((3, 6, 8, 5))
    mx, my, kz_end = rng.integers(0, 2, 6).astype(float), rng.integers(0, 2, 8).astype(float), 3
    mask = mx[:, None, None] * my[None, :, None] * (np.arange(5) < kz_end)
    want = np.empty((6, 8, 5), complex)
    K.truncated_component(u_hat, mx, my, kz_end, 0.5, 1, want)
    assert compiled.fallbacks == []
    assert np.array_equal(want, u_hat[1] * (mask * 0.5))
    wide = np.zeros((3, 6, 8, 10), complex)
    wide[..., ::2] = u_hat
    got = np.empty_like(want)
    K.truncated_component(wide[..., ::2], mx, my, kz_end, 0.5, 1, got)       # not contiguous
    assert np.array_equal(got, want)
    K.truncated_component(u_hat, mx.astype(np.float32), my, kz_end, 0.5, 1, got)  # a dtype
    with pytest.raises(Exception, match="float64"):               # a float for the int:
        K.truncated_component(u_hat, mx, my, kz_end, 0.5, 1.0, got)    # numba's typing error
    assert compiled.fallbacks == [("spectral", "truncated_component")] * 3
    compiled.fallbacks.clear()


def test_ahead_of_time_build_serves_only_current_slots(tmp_path, monkeypatch):
    """A build is used for a slot only if the slot's source is unchanged since, and only on
    the processor and Python it was made for; KAPSEL_PY_AOT=0 ignores it."""
    import json
    import sys
    (tmp_path / "kernels.so").write_bytes(b"")
    rec = {"cpu": compiled.cpu_fingerprint(), "python": list(sys.version_info[:2]),
           "file": "kernels.so", "numba": "x",
           "slots": {"stencils": {"module": "kapsel.mesh.stencils", "signatures": {},
                                  "sha256": compiled.source_sha256("kapsel.mesh.stencils")},
                     "regrid": {"module": "kapsel.mesh.regrid_kernels", "signatures": {},
                                "sha256": "0" * 64}}}
    monkeypatch.setattr(compiled, "AOT_DIR", tmp_path)

    def slots(**changes):
        (tmp_path / (compiled.AOT_MODULE + ".json")).write_text(json.dumps(dict(rec,
                                                                                **changes)))
        monkeypatch.setattr(compiled, "_aot_record", None)
        return set(compiled.aot_slots())
    assert slots() == {"stencils"}                     # regrid's source is not the built one
    assert slots(cpu="another processor") == set()
    assert slots(python=[2, 7]) == set()
    assert slots(file="missing.so") == set()
    monkeypatch.setenv("KAPSEL_PY_AOT", "0")
    assert slots() == set()
    monkeypatch.setattr(compiled, "_aot_record", None)


@pytest.mark.parametrize("method", ["linear", "spline"])
@pytest.mark.parametrize("rows", [None, slice(3, 9)])
def test_compiled_row_shifts_are_bit_identical(method, rows, compiled_kernels):
    """kapsel.mesh.regrid.shift_rows by the compiled kernels gives the numpy passes' bits, for
    vector and scalar fields, negative and non-integer shifts, and a block of x rows."""
    from kapsel.mesh import regrid
    rng = np.random.default_rng(4)
    f = rng.standard_normal((3, 12, 10, 6))
    shift = 2.7 * (np.arange(10) - 4.5)
    compiled_kernels.off()
    assert regrid.kernels is None
    want = regrid.shift_rows(f, shift, method, rows)
    want_scalar = regrid.shift_rows(f[1], shift, method, rows)
    compiled_kernels.on()
    assert regrid.kernels is not None
    got = regrid.shift_rows(f, shift, method, rows)
    got_scalar = regrid.shift_rows(f[1], shift, method, rows)
    compiled_kernels.off()
    assert got.shape == want.shape and got_scalar.shape == want_scalar.shape
    assert np.array_equal(got, want) and np.array_equal(got_scalar, want_scalar)


@pytest.mark.parametrize("shape", [(12, 10, 6), (7, 3, 5), (2, 4, 4), (32, 8, 4)])
def test_compiled_spline_coefficients_are_scipys(shape):
    """The compiled periodic cubic B-spline prefilter gives scipy.ndimage's bits."""
    from scipy.ndimage import spline_filter1d
    from kapsel.mesh import regrid_kernels
    f = np.random.default_rng(7).standard_normal(shape)
    want = spline_filter1d(f, order=3, axis=0, mode="grid-wrap")
    c = np.empty((shape[0], shape[2]))
    every = np.arange(shape[2], dtype=np.int64)
    some = every[::2].copy()                    # a subset of the columns: their own bits
    for j in range(shape[1]):                   # slab by slab, as shift_spline runs it
        regrid_kernels.spline_coefficients(f, j, every, every.size, c)
        assert np.array_equal(c, want[:, j])
        regrid_kernels.spline_coefficients(f, j, some, some.size, c)
        assert np.array_equal(c[:, :some.size], want[:, j, some])


def test_compiled_scatter_adds_as_add_at(compiled_kernels):
    """The particles' increment scattered onto the grid (kapsel.particles.coupling._scatter)
    by the compiled pass: np.add.at's bits, overlapping stencils summed in the same order."""
    from kapsel.particles import coupling
    rng = np.random.default_rng(5)
    idx = rng.integers(0, 50, size=(4, 30))             # overlapping: points repeat
    w = rng.standard_normal((3, 4, 30)) * 10.0 ** rng.integers(-8, 8, size=(3, 4, 30))
    compiled_kernels.off()
    assert coupling._compiled.coupling is None
    want = coupling._scatter(w, idx, 50, shape=(5, 10))
    compiled_kernels.on()
    assert coupling._compiled.coupling is not None
    out = np.full((3, 5, 10), 7.0)
    got = coupling._scatter(w, idx, 50, out=out)
    compiled_kernels.off()
    assert got is out and np.array_equal(got, want)


@pytest.mark.parametrize("dx,strain", [(1.0, 0.0), (0.5, 0.0), (1.0, 0.35), (0.7, -0.8)])
def test_compiled_stencil_points_are_the_numpy_profiles(dx, strain, compiled_kernels):
    """particle_profiles by the compiled pass (kapsel.particles.profile_kernels): the numpy
    passes' indices, offsets and profile, bit for bit, on a plain and an oblique grid, for
    positions inside, outside and on the edges of the box."""
    from kapsel.particles import profile
    shape = (12, 10, 8)
    st = profile.Stencil(2.0, 1.0, dx, strain_max=abs(strain))
    R = np.array([[0.0, 0.0, 0.0], [3.3, 9.99, 7.2], [-1.7, 11.4, 3.5], [11.999, 4.5, 0.01]])
    R = R * dx
    compiled_kernels.off()
    assert profile._compiled.profile is None
    want = profile.particle_profiles(R, st, shape, dx, strain=strain, origin=4.0 * dx)
    compiled_kernels.on()
    assert profile._compiled.profile is not None
    got = profile.particle_profiles(R, st, shape, dx, strain=strain, origin=4.0 * dx)
    compiled_kernels.off()
    for a, b in zip(got, want):
        assert a.shape == b.shape and np.array_equal(a, b)


@pytest.mark.parametrize("clear", [True, False])
def test_compiled_weights_are_the_numpy_passes(clear, compiled_kernels):
    """w = phi / max(phi_sum, 1) at the stencil points by one compiled call
    (coupling_kernels.weights): the numpy passes' bits (np.add.at's order, np.maximum's
    NaN), phi_sum cleared after or kept (walls)."""
    from kapsel.particles import coupling
    rng = np.random.default_rng(8)
    idx = rng.integers(0, 40, size=(5, 24))
    phi = rng.random((5, 24)) * 0.9
    phi[1, 3] = np.nan
    ps0 = np.zeros(40) if clear else rng.random(40) * 0.5       # (the walls' phi)
    ps = ps0.copy()
    np.add.at(ps, idx.reshape(-1), phi.reshape(-1))
    s = ps[idx]
    np.maximum(s, 1.0, out=s)
    want = phi / s
    if clear:
        ps[idx.reshape(-1)] = 0.0
    compiled_kernels.on()
    got_ps, got = ps0.copy(), np.empty_like(phi)
    coupling._compiled.coupling.weights(got_ps, idx, phi, got, clear)
    assert np.array_equal(got, want, equal_nan=True)
    assert np.array_equal(got_ps, ps, equal_nan=True)


def test_compiled_bin_sum_is_bincount(compiled_kernels):
    """The ions' phi and surface charge binned onto the mesh by one compiled pass
    (ions_kernels.bin_sum, kapsel.fluid.ions.set_particles): np.bincount's bits, written
    over whatever the field held."""
    from kapsel.fluid import ions
    rng = np.random.default_rng(9)
    idx = rng.integers(0, 60, size=(3, 40))                # overlapping stencils
    w = rng.standard_normal((3, 40)) * 10.0 ** rng.integers(-6, 6, size=(3, 40))
    want = np.bincount(idx.ravel(), weights=w.ravel(), minlength=60).reshape(3, 4, 5)
    compiled_kernels.on()
    out = np.full((3, 4, 5), np.nan)
    ions._compiled.ions.bin_sum(idx, w, out)
    assert np.array_equal(out, want)


@pytest.mark.parametrize("advect", [True, False])
def test_compiled_ion_passes_are_the_numpy_passes(advect, compiled_kernels):
    """The ions' flux (rows with surface points swept with their test, the others without),
    charge density (the species summed along a row) and Coulomb force (ions_kernels) give
    the numpy passes' bits of kapsel.fluid.ions: surface points in the first and last rows,
    side by side and alone, rows without any."""
    from kapsel.fluid import ions
    rng = np.random.default_rng(4)
    shape = (4, 5, 6)
    size = int(np.prod(shape))
    J0, g, u = (rng.standard_normal((3,) + shape) for _ in range(3))
    c = rng.random(shape)
    E = np.array([0.3, -0.1, 0.0])
    at = np.array([0, 1, 7, 40, 41, 77, size - 1], dtype=np.int64)
    n = rng.standard_normal((3, at.size))
    inv_n2 = 1.0 / (n ** 2).sum(axis=0)
    a, b = 0.7, -1.3
    want = J0.copy()                           # Ions.step's numpy passes
    t = np.empty(shape)
    for d in range(3):
        want[d] *= a
        np.subtract(g[d], E[d], out=t)
        t *= c
        t *= b
        want[d] += t
    Jf = want.reshape(3, -1)
    Jn = Jf[:, at]
    tn = Jn[0] * n[0]
    tn += Jn[1] * n[1]
    tn += Jn[2] * n[2]
    tn *= inv_n2
    for d in range(3):
        Jf[d, at] = Jn[d] - tn * n[d]
    if advect:
        for d in range(3):
            np.multiply(c, u[d], out=t)
            want[d] -= t
    compiled_kernels.on()
    K = ions._compiled.ions
    got = J0.copy()
    K.flux(got, g, E, c, a, b, u, advect, at, n, inv_n2)
    assert np.array_equal(got.view(np.uint64), want.view(np.uint64))
    cs, z = rng.random((2,) + shape), np.array([2.0, -1.0])
    phi, rho_surf = rng.random(shape), rng.standard_normal(shape)
    rho = np.zeros(shape)
    for s in range(2):
        rho = rho + z[s] * cs[s]
    rho = rho * (1.0 - phi) + rho_surf
    out = np.full(shape, np.nan)
    K.charge_density(cs, z, phi, rho_surf, out)
    assert np.array_equal(out.view(np.uint64), rho.view(np.uint64))
    force = np.stack([((E[d] - g[d]) * (rho - rho_surf)) * 0.5 for d in range(3)])
    got_f = np.full((3,) + shape, np.nan)
    got_f[0] = rho                             # rho_e in out[0], as Ions passes it
    K.coulomb_force(E, g, got_f[0], rho_surf, 0.5, got_f)
    assert np.array_equal(got_f.view(np.uint64), force.view(np.uint64))
