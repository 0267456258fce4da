"""The sheared types' start of the particles, as the original's (kapsel.particles.spm
SPM.start_sheared): the given velocities are imposed as deviations from the imposed flow
(sp_3d_ns.cxx main imposes them on the deviation field with its unsheared routines), and only
afterwards V_x = 0, Omega_z = 0 (init_particle.cxx Show_parameter); a continued run keeps the
restart's velocities (the original zeroes them there too: a bug).

Measured against the original (2026-12-01, 16^3, A = 3, one particle given
V = (0.158, 0.5, 0), Shear_Navier_Stokes_Lees_Edwards with Shear_rate 0, 10 steps, the
original's initial zeta packing bug emulated: kapsel.io.restart pack_zeta / unpack_zeta):
max|dV| / max|V| 2.5e-16 with this start, 7.5e-2 with V_x zeroed before the imposition."""
import os

import numpy as np
import pytest

from builders import build, shear_cli, shear_input


V = (0.158, 0.5, 0.03)
W = (0.01, -0.02, 0.015)


def _one_particle(d, eq, rate=0.02, extra=()):
    from udf import UDFManager
    inp = shear_input(d, particles=1, rate=rate, eq=eq, gts=2, nsnap=2)
    u = UDFManager(inp)
    u.put("user_specify", "switch.INIT_distribution.type")
    u.put([[7.6, 10.3, 8.2, *V, 1.0, 0.0, 0.0, 0.0, *W]],
          "switch.INIT_distribution.user_specify.Particles[]")
    for value, path in extra:
        u.put(value, path)
    u.write(inp)
    return inp


def _rectangular_twin(d, eq):
    """The same particle in the type's unsheared twin (Navier_Stokes / Navier_Stokes_FDM)."""
    from udf import UDFManager
    twin = "Navier_Stokes" if eq == "Shear_Navier_Stokes_Lees_Edwards" else "Navier_Stokes_FDM"
    inp = _one_particle(d, "Shear_Navier_Stokes_Lees_Edwards")
    u = UDFManager(inp)
    u.put(twin, "constitutive_eq.type")
    u.put(0.0, f"constitutive_eq.{twin}.kBT")
    u.write(inp)
    return inp


def _velocity(m):
    return np.array(m.spm.velocity(), copy=True)


@pytest.mark.parametrize("eq", ["Shear_Navier_Stokes_Lees_Edwards",
                                "Shear_Navier_Stokes_Lees_Edwards_FDM"])
def test_given_velocities_imposed_as_deviations_then_vx_and_omega_z_zeroed(tmp_path, eq):
    """The initial deviation field is the one the unsheared twin type imposes for the same
    particle (round-off: the oblique frame starts at strain 0), and the particle then holds
    V = (0, V_y, V_z), Omega = (Omega_x, Omega_y, 0)."""
    m = build(_one_particle(tmp_path / "sheared", eq))
    ref = build(_rectangular_twin(tmp_path / "twin", eq))
    u, u0 = _velocity(m), _velocity(ref)
    assert np.abs(u0).max() > 0.1                       # the imposition moved the fluid
    assert np.abs(u - u0).max() < 1e-13 * np.abs(u0).max()
    p = m.particles
    assert p.v[0].tolist() == [0.0, V[1], V[2]]
    assert p.omega[0].tolist() == [W[0], W[1], 0.0]
    assert ref.particles.v[0].tolist() == list(V)        # the unsheared types keep them


def test_zigzag_type_zeroes_vx_and_omega_z_after_the_imposition(tmp_path):
    m = build(_one_particle(tmp_path, "Shear_Navier_Stokes"))
    p = m.particles
    assert p.v[0].tolist() == [0.0, V[1], V[2]]
    assert p.omega[0].tolist() == [W[0], W[1], 0.0]


def test_a_continued_run_keeps_the_restart_velocities(tmp_path):
    """4 + 1 steps written to the restart, then the model continued from it: its particle
    still has the restart's V_x (the flow has moved it) and Omega_z."""
    from udf import UDFManager
    from kapsel import cli as kcli
    inp = _one_particle(tmp_path, "Shear_Navier_Stokes_Lees_Edwards", rate=0.05)
    assert shear_cli(tmp_path, inp) == 0
    cont = str(tmp_path / "continue.udf")
    os.replace(tmp_path / "restart.udf", cont)
    u = UDFManager(cont)
    v = np.array(u.get("resume.CONTINUE.Saved_Data.Particles[0].v"))
    w = np.array(u.get("resume.CONTINUE.Saved_Data.Particles[0].omega"))
    assert abs(v[0]) > 0.1 and abs(w[2]) > 1e-4
    u.put("CONTINUE", "resume.Calculation")
    u.put(4, "output.Num_snap")
    u.write(cont)
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        args = kcli.build_parser().parse_args([f"-I{cont}", "-Ooutput.udf", "-Ddefine.udf",
                                               "-Rrestart.udf", "--quiet", "--overwrite"])
        _, _, model, resumed, *_ = kcli.prepare(args)
    finally:
        os.chdir(cwd)
    assert resumed
    assert model.particles.v[0].tolist() == v.tolist()
    assert model.particles.omega[0].tolist() == w.tolist()


def test_oblique_spectral_state_truncated_every_step():
    """The Lees-Edwards spectral step starts from the 2/3-truncated state (as the original's
    Zeta_k2advection_k_OBL): a mode outside the band put in by add_solenoidal is gone after
    one step, not decaying by the viscous factor only."""
    from kapsel.fluid.oblique import ObliqueSpectralNS
    from kapsel.frame import ShearFlow
    from kapsel.mesh.grid import Grid
    g = Grid((16, 16, 16))
    f = ObliqueSpectralNS(g, 1.0, 1.0, 0.05, ShearFlow("DC", 0.02))
    x = g.coordinates()[0]
    du = np.zeros((3,) + g.shape)
    du[2] = 1e-3 * np.cos(2 * np.pi * 7 * x / 16.0)      # k_x index 7: outside the 2/3 band
    f.add_solenoidal(du)
    assert np.abs(f.velocity()).max() == pytest.approx(1e-3, rel=1e-12)
    f.step()
    assert np.abs(f.velocity()).max() < 1e-16      # (9e-4 without the truncation)
