"""Adding a constitutive_eq.type is one TypeSpec line and the module of its model (its
``@register`` factory), plus the type's block in define.udf (issue 27; kapsel/typespec.py).
The example: "Stokes_test", the spectral Navier-Stokes model without advection, in this
module; the input's definition gets its block; kapsel-py's checks accept it and run it."""
import os
import re

import numpy as np

from kapsel import typespec
from udf import UDFManager

from builders import sample_input

NS_VALUES = "{1.0,1.0,1.0,0.0,1.0,1.0}"


def make_stokes_test(cfg, args, doc):
    """The example type's model: Navier_Stokes's, advection off (Stokes flow)."""
    from kapsel.models.spectral import SpectralModel
    model = SpectralModel(cfg, args)
    model.fluid.advection = False
    return model


def _define_type(text):
    """A definition (define.udf, or an input's header) with the Stokes_test block: the
    Navier_Stokes one renamed, and the name in constitutive_eq.type's select."""
    text = text.replace("'Shear_NS_LE_CH_FDM'}", "'Shear_NS_LE_CH_FDM','Stokes_test'}", 1)
    m = re.search(r"\n\s*Navier_Stokes\s*:\s*\{.*?\}\s*//\s*End Navier_Stokes\n", text, re.S)
    i = re.search(r"\}\s*//\s*End constitutive_eq", text).start()
    return text[:i] + m.group(0).replace("Navier_Stokes", "Stokes_test").lstrip("\n") + text[i:]


def _with_type(text):
    """An input written by UDFManager (its definition inside) with the Stokes_test block
    in the definition and in the data, and constitutive_eq.type Stokes_test."""
    text = _define_type(text)
    line = re.search(r"^constitutive_eq:\{\"Navier_Stokes\",.*\}$", text, re.M)
    new = line.group(0).replace('"Navier_Stokes"', '"Stokes_test"', 1)[:-1] + "," + NS_VALUES + "}"
    return text[:line.start()] + new + text[line.end():]


def _run(d, monkeypatch, new_type):
    from kapsel import Simulation
    u = sample_input(d, "Navier_Stokes", 4)
    u.put(1, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put(0.0, "constitutive_eq.Navier_Stokes.kBT")
    u.put(0.05, "gravity.G")
    u.put(2.0, "object_type.spherical_particle.Particle_spec[0].MASS_RATIO")
    u.write(os.path.join(d, "input.udf"))
    if new_type:
        for name, edit in (("input.udf", _with_type), ("define.udf", _define_type)):
            path = os.path.join(d, name)
            with open(path) as fh:
                text = edit(fh.read())
            with open(path, "w") as fh:
                fh.write(text)
        monkeypatch.setitem(typespec.TYPES, "Stokes_test",
                            typespec.TypeSpec("Stokes_test", "spectral"))
        monkeypatch.setitem(typespec.SOLVERS, "Stokes_test", make_stokes_test)
    sim = Simulation.from_udf(*(os.path.join(d, f) for f in
                                ("input.udf", "output.udf", "define.udf", "restart.udf")),
                              seed=1, overrides={"output.GTS": 2, "output.Num_snap": 2})
    sim.run()
    return sim


def test_a_new_type_is_one_typespec_line_and_its_model(tmp_path, monkeypatch):
    ns = _run(str(tmp_path / "ns"), monkeypatch, False)
    st = _run(str(tmp_path / "st"), monkeypatch, True)
    doc = UDFManager(str(tmp_path / "st" / "input.udf"))
    assert doc.get("constitutive_eq.type") == "Stokes_test"
    assert st.model.cfg.type == "Stokes_test" and st.model.fluid.advection is False
    assert ns.model.fluid.advection is True
    # the same start and forces; the advection term makes the runs differ a little
    vs, vn = st.particles.v, ns.particles.v
    assert np.abs(vs).max() > 0 and not np.array_equal(vs, vn)
    assert np.abs(vs - vn).max() < 0.1 * np.abs(vn).max()
