"""`from UDFManager import *` scripts run unchanged on kapsel-py's output (OCTA's API,
FORMAT.md "OCTA's Python UDFManager"; udf/octa.py)."""
import os
import subprocess
import sys
import textwrap

import pytest

from builders import make_input


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A short run of the sample (16^3, 2 particles, 2 snapshots)."""
    d = tmp_path_factory.mktemp("octa")
    make_input(d, "Navier_Stokes_Cahn_Hilliard_FDM", particles=2, gts=2, nsnap=2, kBT=0.0)
    r = subprocess.run([sys.executable, "-m", "kapsel.cli", "-Iinput.udf", "-Ooutput.udf",
                        "-Ddefine.udf", "-Rrestart.udf", "--seed", "1", "--quiet"],
                       cwd=d, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return d


def script(d, body):
    """Run a user's script in a fresh interpreter, as `python -c` would."""
    r = subprocess.run([sys.executable, "-c", textwrap.dedent(body)], cwd=d,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout


def test_octa_script_runs_unchanged(run_dir):
    out = script(run_dir, """
        from UDFManager import *
        u = UDFManager('output.udf')
        spec = u.getArray('object_type.spherical_particle.Particle_spec[]')
        print(repr(spec))
        print(u.getEngineName(), u.getEngineVersion())
        print(u.totalRecord())
        for rec in range(u.totalRecord()):
            if u.jump(rec) != rec:
                raise SystemExit('jump')
            R = u.getArray('Particles[].R')
            assert type(R) is list and len(R) == 2 and len(R[0]) == 3
            assert u.get('Particles[].R', [1]) == R[1]
            assert u.get('Particles[].R.x', [0]) == R[0][0]
            assert u.size('Particles[]') == 2
        print(u.jump(u.totalRecord() + 5))
        u.jump(-1)
        print(u.get('mesh.NPX'), u.get('constitutive_eq.type'))
        print(u.udfFile().endswith('output.udf'))
    """)
    lines = out.splitlines()
    spec = eval(lines[0])
    # a list of lists, one per species, members of their own types
    assert isinstance(spec, list) and isinstance(spec[0], list)
    assert spec[0][0] == 2 and isinstance(spec[0][0], int) and spec[0][3] == "NONE"
    assert lines[1] == "Kapsel v3.4"
    assert lines[2] == "3"
    assert lines[3] == "2"                       # jump past the end: the last record
    assert lines[4] == "4 Navier_Stokes_Cahn_Hilliard_FDM"
    assert lines[5] == "True"


def test_octa_put_write_records_and_locations(run_dir, tmp_path):
    from UDFManager import Location, UDFManager, rlocation
    u = UDFManager(str(run_dir / "output.udf"))
    assert Location("Particles[].R", [1]).str() == "Particles[1].R"
    assert rlocation("Particles[].R.x", [0]).str() == "Particles[0].R.x"
    loc = Location("Particles[]", [0])
    assert loc.next().str() == "Particles[1]" and loc.sub("v").str() == "Particles[1].v"
    u.jump(1)
    assert u.get(Location("Particles[].R", [1])) == u.get("Particles[1].R")
    u.put(1.25, "Particles[].R.x", [0])                  # value first
    assert u.get("Particles[0].R.x") == 1.25
    n = u.newRecord()
    assert n == 3 and u.totalRecord() == 4
    u.eraseRecord(record_pos=3, record_num=1)
    assert u.totalRecord() == 3
    copy = str(tmp_path / "copy.udf")
    u.write(copy)
    v = UDFManager(copy)
    assert v.totalRecord() == 3 and v.jump(1) == 1 and v.get("Particles[0].R.x") == 1.25
    u.jump(2)
    u.write(str(tmp_path / "one.udf"), record=1)         # the current record only
    assert UDFManager(str(tmp_path / "one.udf")).totalRecord() == 1
    u.write(str(tmp_path / "one.udf"), record=1, mode=1)  # appended
    assert UDFManager(str(tmp_path / "one.udf")).totalRecord() == 2
    with pytest.raises(RuntimeError):
        u.get("no_such_item")
    with pytest.raises(IndexError):
        u.get("Particles[7].R")
    with pytest.raises(RuntimeError):
        UDFManager(str(tmp_path / "missing.udf"))
