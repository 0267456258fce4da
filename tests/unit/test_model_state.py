"""kapsel.state.ModelState: a model's step-to-step fields in one place (issue 27).

Every type's model keeps the fields its next step needs in ``model.state``: the solvers'
persistent arrays are the state's own (not copies), the previous steps are held only once a
step made them, and the restart's fields are read from the state by name."""
import numpy as np
import pytest

from kapsel import typespec
from kapsel.state import ModelState

from builders import (build, electrolyte_input, fdm_input, sample_input, shear_input,
                      write_input)

pytestmark = pytest.mark.unit

# what each family carries from one step to the next (kapsel/state.py)
SPECTRAL = {"u_hat"}
MAC = {"u", "u_old", "pressure", "phi_prev"}
EXPECTED = {
    "Navier_Stokes": SPECTRAL,
    "Shear_Navier_Stokes": SPECTRAL,
    "Shear_Navier_Stokes_Lees_Edwards": SPECTRAL,
    "Electrolyte": SPECTRAL | {"ion_c", "ion_c_hat"},
    "Navier_Stokes_FDM": MAC | {"n_old"},                       # explicit scheme: AB2
    "Navier_Stokes_Cahn_Hilliard_FDM": MAC | {"psi", "psi_old", "capillary_force", "n_old"},
    "Shear_Navier_Stokes_Lees_Edwards_FDM": MAC | {"n_old"},
    "Shear_NS_LE_CH_FDM": MAC | {"psi", "psi_old", "capillary_force", "n_old"},
}


def _model(d, eq):
    if eq == "Electrolyte":
        return build(electrolyte_input(d, npx=3))
    if eq == "Shear_Navier_Stokes_Lees_Edwards":
        return build(shear_input(d, particles=1))
    if eq in ("Shear_Navier_Stokes_Lees_Edwards_FDM", "Shear_NS_LE_CH_FDM"):
        return build(fdm_input(d, eq=eq, particles=1))
    u = sample_input(d, eq, npx=3)
    u.put(1.5, "A")
    u.put(1, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put("explicit_scheme", "constitutive_eq.Navier_Stokes_FDM.NS_solver.type")
    return build(write_input(u, d, 2, 2))


def test_fields_are_made_once_and_held_when_set():
    st = ModelState()
    a = st.field("u_old", lambda: np.zeros(3), held=False)
    assert st.field("u_old", lambda: np.ones(3)) is a          # made once
    assert not st.holds("u_old") and st.get("u_old") is None
    st.mark("u_old")
    assert st.get("u_old") is a
    st.put("psi_old", np.ones(2))
    assert st.holds("psi_old") and st.names() == ["u_old", "psi_old"]
    st.put("psi_old", None)
    assert not st.holds("psi_old") and "psi_old" not in st
    with pytest.raises(KeyError):
        st.mark("nothing")


@pytest.mark.parametrize("eq", typespec.names())
def test_every_type_keeps_its_step_to_step_fields_in_its_state(tmp_path, eq):
    m = _model(str(tmp_path), eq)
    # before the first step no previous step is held
    assert not any(m.state.holds(n) for n in ("u_old", "n_old", "psi_old", "phi_prev"))
    m.advance()
    m.advance()
    st = m.state
    assert set(st.names()) == EXPECTED[eq], st
    assert all(st.holds(n) for n in st.names()), st        # two steps made every one
    fluid = getattr(m, "fluid", None) or m.mac
    if "u_hat" in st:
        assert fluid.u_hat is st["u_hat"]
    else:                       # MAC: the velocity, its previous step, the pressure
        assert m.u is st["u"] and m.spm.u is st["u"]
        assert m.mac.u_old is st["u_old"] and m.mac.pressure is st["pressure"]
    if "ion_c" in st:
        assert m.ions.c is st["ion_c"]
    if "psi" in st:
        assert m.psi is st["psi"] and m.ch.psi_old is st["psi_old"]
        assert m.last_force is st["capillary_force"]


@pytest.mark.parametrize("eq", ["Navier_Stokes_Cahn_Hilliard_FDM", "Navier_Stokes"])
def test_the_restart_is_read_from_the_state(tmp_path, eq):
    """What the restart writes is the state's: change a field of the state and the
    restart's field changes alike."""
    m = _model(str(tmp_path), eq)
    m.advance()
    m.advance()
    if eq == "Navier_Stokes":
        m.state["u_hat"][...] *= 2.0
        _, _, exact = m.restart_state()
        assert np.array_equal(exact["u_hat"], m.state["u_hat"])
        return
    m.state["psi_old"][...] = 0.25
    m.state["u_old"][...] = -1.0
    _, fields, _ = m.restart_state()
    assert np.all(fields["PSI_OLD"] == 0.25)
    assert np.all(np.asarray(fields["U_OLD"]) == -1.0)
