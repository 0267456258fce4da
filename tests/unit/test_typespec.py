"""kapsel.typespec: the one registry of constitutive_eq types."""
import re

from kapsel import typespec
from kapsel.typespec import SOLVERS

from builders import TESTS


def test_every_type_has_a_model_and_every_model_a_type():
    import kapsel.models  # noqa: F401  (registers the factories)
    assert set(SOLVERS) == set(typespec.TYPES)


def test_the_schema_names_no_type_the_registry_lacks():
    """No define.udf of the repository (versions 3.02 to 4.1) offers a type the registry
    does not know."""
    import glob
    import os
    root = os.path.join(TESTS, "..", "samples")
    found = set()
    for path in glob.glob(os.path.join(root, "**", "define.udf"), recursive=True):
        text = open(path, encoding="utf-8", errors="replace").read()
        m = re.search(r"constitutive_eq:\s*\{\s*type:\s*select\s*\{([^}]*)\}", text)
        if m:
            found |= set(re.findall(r"'([A-Za-z_]+)'", m.group(1)))
    assert found and found <= set(typespec.TYPES), found - set(typespec.TYPES)


def test_names_selects_by_attributes():
    assert typespec.names(phase=True) == ("Navier_Stokes_Cahn_Hilliard_FDM",
                                          "Shear_NS_LE_CH_FDM")
    assert set(typespec.names(sheared=True)) == {n for n in typespec.TYPES if "Shear" in n}
    assert typespec.names(grid="fdm") == tuple(n for n in typespec.TYPES if "FDM" in n)
    assert not typespec.spec("Electrolyte").distributed
