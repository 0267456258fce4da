"""Shared by every tier of the tests (tests/unit, tests/integration, tests/validation,
tests/distributed; conftest.py puts tests/ on sys.path): the input builders (the manual's
sample and the examples shrunk to small meshes), the runs of the command (main() in a
directory, one seed per family of tests), the readers of what a run leaves behind, and the
measurements more than one tier makes.  No test module imports another: what two of them
share lives here, once."""
import json
import math
import os
import shutil
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
from scipy.integrate import quad

from kapsel import Simulation, config
from kapsel.cli import main
from kapsel.io.fields import SnapshotFiles
from kapsel.io.restart import state_path
from kapsel.particles.spm import SPM
from kapsel.particles.state import ParticleState
from kapsel.snapshot import Snapshot
from udf import UDFManager

# tests/: the data, bad inputs and helper scripts the tiers share (each tier is a directory
# below it: unit, integration, validation, distributed)
TESTS = os.path.dirname(os.path.abspath(__file__))
SAMPLES = os.path.join(TESTS, "..", "samples")



def write_input(u, d, gts, nsnap):
    """``u`` with output.GTS and output.Num_snap set, written as d/input.udf (its path)."""
    u.put(gts, "output.GTS")
    u.put(nsnap, "output.Num_snap")
    path = os.path.join(d, "input.udf")
    u.write(path)
    return path

def copy_schema(d, src=SAMPLES):
    """define.udf and kapsel_unit.udf of the directory ``src`` (the manual's sample) copied
    to the run directory ``d``: what every input beside them needs."""
    for f in ("define.udf", "kapsel_unit.udf"):
        shutil.copy(os.path.join(src, f), os.path.join(d, f))


def sample_input(d, eq, npx=4):
    """The manual's sample in directory ``d`` (its define.udf and kapsel_unit.udf copied
    there) as a UDFManager, with constitutive_eq.type ``eq`` and 2^npx cells per side; the
    caller puts the rest and writes it."""
    os.makedirs(d, exist_ok=True)
    copy_schema(d)
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u.put(eq, "constitutive_eq.type")
    for k in ("NPX", "NPY", "NPZ"):
        u.put(npx, f"mesh.{k}")
    return u


def sample_copy(tmp_path, *pairs, text=None):
    """The manual's sample input (or ``text``) in ``tmp_path`` with its define.udf and
    kapsel_unit.udf, each (old, new) of ``pairs`` replaced once (old must be there); returns
    the input's path."""
    copy_schema(tmp_path)
    text = text if text is not None else open(os.path.join(SAMPLES, "input.udf")).read()
    for old, new in pairs:
        assert old in text, old
        text = text.replace(old, new, 1)
    (tmp_path / "input.udf").write_text(text)
    return str(tmp_path / "input.udf")


def continue_input(d, num_snap=4) -> str:
    """``d``/cont.udf: ``d``/restart.udf as the input of a continued run (output.Num_snap
    raised to ``num_snap``), with the restart's state file beside it; returns its path."""
    from kapsel.io.restart import state_path
    rs = UDFManager(os.path.join(d, "restart.udf"))
    rs.put(num_snap, "output.Num_snap")
    cont = os.path.join(d, "cont.udf")
    rs.write(cont)
    shutil.copy(state_path(os.path.join(d, "restart.udf")), state_path(cont))
    return cont


def run_cli(d, inp, *extra, seed):
    """kapsel-py -I<inp> -Ooutput.udf -Ddefine.udf -Rrestart.udf --seed <seed> --quiet
    <extra> run in directory ``d``; returns the exit code."""
    cwd = os.getcwd()
    os.chdir(d)
    try:
        return main([f"-I{inp}", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--seed",
                     str(seed), "--quiet", *extra])
    finally:
        os.chdir(cwd)


def scene(d, base, puts, name="input.udf"):
    """An input made as the comparisons with the original were (the kref tools' mkscene.py):
    the input ``base`` with the (path, value) ``puts`` put in order, written to ``d``/name
    next to the base's define.udf (and kapsel_unit.udf); returns its path."""
    os.makedirs(d, exist_ok=True)
    for f in ("define.udf", "kapsel_unit.udf"):
        src = os.path.join(os.path.dirname(base), f)
        if os.path.exists(src):
            shutil.copy(src, os.path.join(d, f))
    u = UDFManager(base)
    for path, value in puts:
        u.put(value, path)
    path = os.path.join(d, name)
    u.write(path)
    return path


def run_model(path, steps):
    """The model of the input ``path`` as the command line builds it (seed 1), after
    ``steps`` steps."""
    from kapsel import simulation
    from kapsel.cli import build_parser, prepare
    cwd = os.getcwd()
    os.chdir(os.path.dirname(os.path.abspath(path)))
    try:
        args = build_parser().parse_args([f"-I{os.path.basename(path)}", "-Oout.udf",
                                          "-Ddefine.udf", "-Rrestart.udf", "--quiet",
                                          "--seed", "1"])
        args.dist = None
        prepared = prepare(args, None)
        assert not isinstance(prepared, int), "the input was refused"
        model = prepared[2]
        for _ in range(steps):
            simulation.advance(model)
    finally:
        os.chdir(cwd)
    return model


# ---------------------------------------------------------------- from test_restart.py
NS_CH = "constitutive_eq.Navier_Stokes_Cahn_Hilliard_FDM"


def make_input(d, eq, ns="implicit_scheme", ch="implicit_scheme", particles=3, gts=2,
               nsnap=2, kBT=0.5, npx=4):
    """The manual's sample shrunk to 2^npx cells per side, with noise (kBT) on."""
    u = sample_input(d, eq, npx)
    for t in ("Navier_Stokes", "Navier_Stokes_FDM", "Navier_Stokes_Cahn_Hilliard_FDM"):
        u.put(kBT, f"constitutive_eq.{t}.kBT")
    u.put(ns, f"{NS_CH}.NS_solver.type")
    u.put(ch, f"{NS_CH}.CH_solver.type")
    u.put(ns, "constitutive_eq.Navier_Stokes_FDM.NS_solver.type")
    u.put(particles, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    return write_input(u, d, gts, nsnap)


def cli(d, inp, *extra):
    """run_cli with the seed of the restart, robustness and distributed tests."""
    return run_cli(d, inp, *extra, seed=11)


def saved_data(path):
    doc = UDFManager(path)
    kind = doc.get("resume.Calculation")
    base = f"resume.{kind}.Saved_Data"
    out = {"jikan": np.array(doc.get(f"{base}.jikan"), dtype=float)}
    for name in ("Particles", "U", "U_OLD", "PSI", "PSI_OLD", "Zeta", "uk_dc"):
        try:
            if doc.size(f"{base}.{name}[]"):
                out[name] = np.asarray(doc.getArray(f"{base}.{name}[]"), dtype=float)
        except Exception:
            pass
    with np.load(state_path(path)) as z:
        for k in z.files:
            if z[k].dtype.kind != "U":
                out["state:" + k] = z[k]
            elif k.startswith("checkpoint:value:"):        # schema values kept as JSON
                v = json.loads(str(z[k]))
                try:
                    out["state:" + k] = np.asarray(v, dtype=float)
                except (TypeError, ValueError):
                    out["state:" + k] = str(z[k])
            elif k not in ("fingerprint", "run_id", "checkpoint:base"):   # identities
                # (checkpoint:base: the restart.udf a full state file also continues)
                out["state:" + k] = str(z[k])
    return out


def records(path):
    doc = UDFManager(path)
    out = []
    for n in range(doc.totalRecord()):
        doc.jump(n)
        out.append((doc.get("t"), doc.getArray("Particles[].R") if doc.size("Particles[]")
                    else None))
    return out



# ---------------------------------------------------------------- from test_shear_le.py
def original_ac_strains(shear, dt, n):
    """The strains the original's AC frame holds after 0 .. n steps (sp_3d_ns.cxx: after
    the fluid step of step ts, degree_oblique += Shear_rate cos(omega dt ts) dt), summed
    step by step as it does."""
    g, out = 0.0, [0.0]
    for ts in range(n):
        g += shear.rate0 * math.cos(shear.omega * dt * ts) * dt
        out.append(g)
    return out


def shearing_wave(grid, shear, nu, t, m=(1, 2), a=1e-3, inplane=False, y0=None, frame=0.0,
                  dt=None):
    """Exact linear solution advected by U = gamma_dot (y - y0) e_x on the rectangular grid:
    out of plane u_z = A(t) cos(K(t).x + phase), or in plane from the vorticity
    omega_z = A(t) cos(...) (u = curl psi, -lap psi = omega); A(t) = a exp(-nu int |K|^2).
    ``frame`` g: on the oblique grid of strain g instead (x = i + g (j - y0)).
    ``dt`` (AC): the solution of the original's discrete AC frame instead, strain Gamma_n
    (``original_ac_strains``) and A = a exp(-nu dt sum_{m<n} |K(Gamma_m)|^2) (its metric of
    each step's start)."""
    x, y, z = grid.coordinates()
    L = grid.box
    y0 = 0.5 * L[1] if y0 is None else y0
    x = x + frame * (y - y0)
    k1, k2 = 2 * np.pi * m[0] / L[0], 2 * np.pi * m[1] / L[1]
    if dt is not None:
        gs = original_ac_strains(shear, dt, int(round(t / dt)))
        G = gs[-1]
        integral = dt * sum(k1 ** 2 + (k2 - k1 * gm) ** 2 for gm in gs[:-1])
    else:
        G = shear.strain(t)
        integral = quad(lambda s: k1 ** 2 + (k2 - k1 * shear.strain(s)) ** 2, 0, t,
                        limit=200)[0]
    Ky = k2 - k1 * G
    amp = a * math.exp(-nu * integral)
    ph = k1 * x + Ky * y + k1 * G * y0 + 0 * z
    u = np.zeros((3,) + grid.shape)
    if inplane:
        K2 = k1 ** 2 + Ky ** 2
        u[0] = -amp / K2 * Ky * np.sin(ph)
        u[1] = amp / K2 * k1 * np.sin(ph)
    else:
        u[2] = amp * np.cos(ph)
    return u


def shear_input(d, particles=1, kind="DC", rate=0.02, freq=0.0, gts=10, nsnap=2, npx=4,
               obl="linear", eq="Shear_Navier_Stokes_Lees_Edwards"):
    from udf import UDFManager
    os.makedirs(d, exist_ok=True)
    copy_schema(d)
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u.put(eq, "constitutive_eq.type")
    base = f"constitutive_eq.{eq}"
    u.put(kind, f"{base}.External_field.type")
    u.put(rate, f"{base}.External_field.{kind}.Shear_rate")
    if kind == "AC":
        u.put(freq, f"{base}.External_field.AC.Frequency")
    u.put(0.0, f"{base}.kBT")
    for k in ("NPX", "NPY", "NPZ"):
        u.put(npx, f"mesh.{k}")
    u.put(particles, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put(obl, "switch.ns_solver.OBL_INT")
    return write_input(u, d, gts, nsnap)


def build(inp):
    from kapsel import config, models  # noqa: F401
    from kapsel.typespec import SOLVERS
    import udf
    doc = udf.UDFManager(inp)
    cfg = config.from_document(doc, inp)
    return SOLVERS[cfg.type](cfg, SimpleNamespace(seed=3, quiet=True, threads=1), doc)


def shear_cli(d, inp, *extra):
    """run_cli with the seed of the sheared types' and the self-propelled particles' tests."""
    return run_cli(d, inp, *extra, seed=5)


def bodies_input(d, eq, obj, **kw):
    """A sheared input with 2 chains of 3 beads or 2 free rigid bodies of 2 beads (A = 2)."""
    from udf import UDFManager
    if eq.endswith("FDM"):
        inp = fdm_input(d, particles=0, eq=eq, **kw)
    else:
        inp = shear_input(d, particles=0, eq=eq, **kw)
    u = UDFManager(inp)
    u.put(2.0, "A")
    u.put(obj, "object_type.type")
    if obj == "chain":
        u.put([[3, 2, 1.0, 0.0, "NONE"]], "object_type.chain.Chain_spec[]")
    else:
        u.put([[2, 2, 1.0, 0.0, "free", [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]],
              "object_type.rigid.Rigid_spec[]")
    u.put("ON", "switch.LJ_truncate")
    u.write(inp)
    return inp



# ---------------------------------------------------------------- from test_shear_fdm.py
LE_FDM = "Shear_Navier_Stokes_Lees_Edwards_FDM"
LE_CH = "Shear_NS_LE_CH_FDM"


def fdm_input(d, eq=LE_FDM, ns="explicit_scheme", ch="implicit_scheme", particles=0,
              viscosity=None, dt=None, **kw):
    """``dt``: a manual time step (default: the automatic one)."""
    from udf import UDFManager
    inp = shear_input(d, particles=particles, eq=eq, **kw)
    u = UDFManager(inp)
    base = f"constitutive_eq.{eq}"
    if dt is not None:
        u.put("manual", "time_increment.type")
        u.put(dt, "time_increment.manual.delta_t")
    u.put(ns, f"{base}.NS_solver.type")
    if eq == LE_CH:
        u.put(ch, f"{base}.CH_solver.type")
        if viscosity is not None:
            u.put("ON", f"{base}.NS_solver.implicit_scheme.viscosity_change")
            u.put(viscosity[0], f"{base}.NS_solver.implicit_scheme.ON.ETA_A")
            u.put(viscosity[1], f"{base}.NS_solver.implicit_scheme.ON.ETA_B")
    u.write(inp)
    return inp



# ---------------------------------------------------------------- from test_fields.py
SHAPE = (8, 4, 2)  # (NX, NY, NZ), non-cubic on purpose
DX = 0.5
DT = 0.0625
GTS = 2
NSCH = "Navier_Stokes_Cahn_Hilliard_FDM"


def psi_at(X, Y, Z, t):
    return np.sin(X) + 10.0 * Y + 100.0 * Z + 1000.0 * t


def u_at(X, Y, Z, t):
    return (X + t, -2.0 * Y + 3.0 * t, 5.0 * Z - t + X * Y)


def fake_snapshot(step, n_particles=3, shape=SHAPE, strain=0.0):
    """A Snapshot of analytic fields (functions of the physical point) at step."""
    t = step * DT
    nx, ny, nz = shape
    X, Y, Z = np.meshgrid(np.arange(nx) * DX, np.arange(ny) * DX, np.arange(nz) * DX,
                          indexing="ij")
    p = ParticleState.spheres([0] * n_particles, [1.0] * n_particles, [1.0] * n_particles, 1.0)
    k = np.arange(n_particles)[:, None]
    p.R[:] = 0.25 + k * np.array([1.0, 0.5, 0.25]) + t
    p.v[:] = k * np.array([-1.0, 2.0, 3.0]) - t
    u = np.stack(u_at(X, Y, Z, t))
    src = {"u": lambda: u, "psi": lambda: psi_at(X, Y, Z, t), "phi": lambda: 0.5 + 0.1 * X - Y * t,
           "flux": lambda: 2.0 * u}
    src["psi_all"] = src["psi"]
    return Snapshot(step=step, time=t, dt=DT, shape=shape, dx=DX, particles=p, strain=strain,
                    sources=src)


def write_series(directory, eq=NSCH, steps=(0, 2, 4), n_particles=3, resumed=False):
    w = SnapshotFiles(directory, eq, SHAPE, DX, GTS, n_particles)
    snaps = [fake_snapshot(s, n_particles) for s in steps]
    w.open(snaps[0], resumed)
    for s in snaps:
        w.write(s)
    w.close("end")
    return w


def vtk_reader(path):
    import pytest
    xdmf2 = pytest.importorskip(
        "vtkmodules.vtkIOXdmf2",
        reason="VTK (pip install vtk) is needed to check the files with ParaView's XDMF reader")
    from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline as SDDP
    r = xdmf2.vtkXdmfReader()
    r.SetFileName(str(path))
    r.UpdateInformation()
    steps = r.GetOutputInformation(0).Get(SDDP.TIME_STEPS())
    return r, tuple(steps or ())


def vtk_at(reader, t):
    from vtkmodules.util.numpy_support import vtk_to_numpy
    reader.UpdateTimeStep(t)
    data = reader.GetOutputDataObject(0)
    pd = data.GetPointData()
    arrays = {pd.GetArrayName(i): vtk_to_numpy(pd.GetArray(i))
              for i in range(pd.GetNumberOfArrays())}
    return data, arrays


def run_dt(d):
    from kapsel import config
    from kapsel.models.common import time_step
    return time_step(config.load(os.path.join(d, "input.udf")))



# ---------------------------------------------------------------- from test_fdm_model.py
def fdm_sample(tmp_path, gts=5, nsnap=2, ns="explicit_scheme", ch="implicit_scheme",
           particles=8, manual_dt=None, eq="Navier_Stokes_Cahn_Hilliard_FDM"):
    """The manual's sample input with a few settings changed through the UDF API."""
    copy_schema(tmp_path)
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u.put(eq, "constitutive_eq.type")
    u.put(ns, f"{NS_CH}.NS_solver.type")
    u.put(ch, f"{NS_CH}.CH_solver.type")
    u.put(ns, "constitutive_eq.Navier_Stokes_FDM.NS_solver.type")
    u.put(particles, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put(gts, "output.GTS")
    u.put(nsnap, "output.Num_snap")
    if manual_dt:
        u.put("manual", "time_increment.type")
        u.put(manual_dt, "time_increment.manual.delta_t")
    path = tmp_path / "input.udf"
    u.write(str(path))  # a self-contained input: our own output is a valid input
    return str(path)


class Args:
    seed = 7
    quiet = True
    threads = 1



# ---------------------------------------------------------------- from test_extended.py
CROP = [(1, 5, 3), (0, 16, 1), (2, 3, 6)]      # (start, count, stride) per axis, 16^3 mesh


def extended_input(d, eq, crop=None, pressure=True, particles=2, gts=2, nsnap=2,
                   file_type="EXTENDED"):
    from udf import UDFManager
    inp = make_input(d, eq if "Shear" not in eq else "Navier_Stokes", particles=particles, gts=gts,
                     nsnap=nsnap, kBT=0.0)
    u = UDFManager(inp)
    if "Shear" in eq:
        u.put(eq, "constitutive_eq.type")
        base = f"constitutive_eq.{eq}"
        u.put("DC", f"{base}.External_field.type")
        u.put(0.05, f"{base}.External_field.DC.Shear_rate")
        u.put(0.0, f"{base}.kBT")
    u.put("ON", "output.AVS")
    u.put("out", "output.ON.Out_dir")
    u.put("traj", "output.ON.Out_name")
    u.put(file_type, "output.ON.FileType")
    pf = "output.ON.EXTENDED.Print_field"
    u.put("YES" if crop else "NO", f"{pf}.Crop")
    for ax, slab in zip("xyz", crop or CROP):
        u.put(list(slab), f"{pf}.YES.Slab_{ax}")
    for flag in ("Vel", "Phi", "Tau"):
        u.put("YES", f"{pf}.{flag}")
    u.put("YES" if pressure else "NO", f"{pf}.Pressure")
    u.put("YES", f"{pf}.Charge")           # forced off, as the original does for these types
    u.write(inp)
    return inp



# ---------------------------------------------------------------- from test_avs.py
def with_stress(snap):
    """The fake snapshot plus pressure and tau (distinct analytic fields)."""
    u = snap.get("u")
    snap.sources["pressure"] = lambda: 7.0 * u[0] - u[2]
    snap.sources["tau"] = lambda: np.stack([u[0] + 10 * k for k in range(5)])
    return snap



# ---------------------------------------------------------------- from test_api.py
SEED = 7
SMALL = {"output.GTS": 5, "output.Num_snap": 4, "A": 2.0}


def api_input(d, eq):
    u = sample_input(d, eq)
    for k, v in SMALL.items():
        u.put(v, k)
    u.write(os.path.join(d, "input.udf"))


def api_simulation(d, **kw):
    return Simulation.from_udf(os.path.join(d, "input.udf"), os.path.join(d, "output.udf"),
                               os.path.join(d, "define.udf"), os.path.join(d, "restart.udf"),
                               seed=SEED, **kw)



# ---------------------------------------------------------------- from test_reliability.py
def one_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert "Traceback" not in err, err
    assert len(lines) == 1, err
    return lines[0]



# ---------------------------------------------------------------- from test_electrolyte.py
EX01 = os.path.join(TESTS, "..", "samples", "kapsel-udf", "ex01")
EL = "constitutive_eq.Electrolyte"


def electrolyte_input(d, npx=4, particles=None, salt=True, field="DC", init="Uniform", gts=2,
               nsnap=2, charge=-20.0, debye=3.0, A=3.0):
    """ex01/colloid_1.udf shrunk to 2^npx cells per side; ``particles``: user positions."""
    os.makedirs(d, exist_ok=True)
    shutil.copy(os.path.join(EX01, "define.udf"), os.path.join(d, "define.udf"))
    u = UDFManager(os.path.join(EX01, "colloid_1.udf"))
    for k in ("NPX", "NPY", "NPZ"):
        u.put(npx, f"mesh.{k}")
    n = 2 ** npx
    if particles is None:
        particles = [[n / 4, n / 4, n / 4], [3 * n / 4 - 0.3, 3 * n / 4, n / 2 + 0.2]]
    u.put(len(particles), "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put(charge, "object_type.spherical_particle.Particle_spec[0].Surface_charge")
    rows = np.array([list(map(float, p)) + [0.0] * 3 + [1.0, 0.0, 0.0, 0.0] + [0.0] * 3
                     for p in particles])
    u.put(rows, "switch.INIT_distribution.user_specify.Particles[]")
    u.put(A, "A")
    u.put(init, f"{EL}.INIT_profile")
    u.put("salt" if salt else "saltfree", f"{EL}.Add_salt.type")
    u.put(debye, f"{EL}.Add_salt.salt.Debye_length")
    u.put("OFF" if field == "OFF" else "ON", f"{EL}.Electric_field.type")
    if field != "OFF":
        u.put(field, f"{EL}.Electric_field.ON.type")
    u.put(gts, "output.GTS")
    u.put(nsnap, "output.Num_snap")
    u.put("OFF", "output.AVS")
    u.put("ON", "output.UDF")
    path = os.path.join(d, "input.udf")
    u.write(path)
    return path


def electrolyte_cli(d, inp, *extra):
    """run_cli with the seed of the Electrolyte tests."""
    return run_cli(d, inp, *extra, seed=3)


def model_of(path, **kw):
    from kapsel.models.electrolyte import ElectrolyteModel

    class Args:
        quiet, threads, seed = True, 1, 1
    cfg = config.load(path)
    return ElectrolyteModel(cfg, Args())


def sample_el_input(d):
    """The manual's sample as a salt-free Electrolyte run, 16^3, two particles of Z = -10,
    EXTENDED output with every print switch on."""
    os.makedirs(d, exist_ok=True)
    copy_schema(d)
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u.put("Electrolyte", "constitutive_eq.type")
    for k, v in (("DX", 1.0), ("RHO", 1.0), ("ETA", 1.0), ("kBT", 1.0), ("alpha_v", 1.0),
                 ("alpha_o", 1.0), ("Dielectric_cst", 1.0), ("INIT_profile", "Poisson_Boltzmann"),
                 ("Add_salt.type", "saltfree"), ("Add_salt.saltfree.Valency_counterion", 1.0),
                 ("Add_salt.saltfree.Onsager_coeff_counterion", 1.0),
                 ("Electric_field.type", "OFF")):
        u.put(v, f"{EL}.{k}")
    for k in ("NPX", "NPY", "NPZ"):
        u.put(4, f"mesh.{k}")
    u.put(2, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put(-10.0, "object_type.spherical_particle.Particle_spec[0].Surface_charge")
    u.put(3.0, "A")
    u.put(2, "output.GTS")
    u.put(2, "output.Num_snap")
    u.put("ON", "output.AVS")
    u.put("EXTENDED", "output.ON.FileType")
    for k in ("Vel", "Phi", "Charge", "Pressure", "Tau"):
        u.put("YES", f"output.ON.EXTENDED.Print_field.{k}")
    u.put("NO", "output.ON.EXTENDED.Print_field.Crop")
    path = os.path.join(d, "input.udf")
    u.write(path)
    return path



# ---------------------------------------------------------------- from test_rigid.py
def rigid_input(tmp_path, specs, eq="Navier_Stokes", name="rigid.udf", raw=None, **puts):
    copy_schema(tmp_path)
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u.put(eq, "constitutive_eq.type")
    u.put("rigid", "object_type.type")
    u.put([[nb, n, mr, 0.0, motion, list(v), list(w)] for nb, n, mr, motion, v, w in specs],
          "object_type.rigid.Rigid_spec[]")
    u.put("ON", "switch.LJ_truncate")
    for path, value in puts.items():
        u.put(value, path.replace("__", "."))
    for path, value in (raw or {}).items():
        u.put(value, path)
    u.write(str(tmp_path / name))
    return str(tmp_path / name)


FREE3 = (3, 3, 1.5, "free", (0, 0, 0), (0, 0, 0))



# ---------------------------------------------------------------- from test_walls.py
EX14 = os.path.join(TESTS, "..", "samples", "kapsel-udf", "ex14")


def wall_run_input(tmp_path, eq, n=2, steps=(5, 2)):
    text = open(os.path.join(EX14, "input.udf")).read()
    text = text.replace('"Navier_Stokes_Cahn_Hilliard_FDM"', f'"{eq}"', 1)
    text = text.replace('[{0,2.00000000000000,0.0,"NONE"', f'[{{{n},2.00000000000000,0.0,"NONE"', 1)
    text = text.replace("output:{100,200,", "output:{%d,%d," % steps, 1)
    return text



# ---------------------------------------------------------------- from test_chains.py
def chain_input(tmp_path, specs=((6, 2),), eq="Navier_Stokes", **puts):
    copy_schema(tmp_path)
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u.put(eq, "constitutive_eq.type")
    u.put("chain", "object_type.type")
    u.put([[nb, n, 1.0, 0.0, "NONE"] for nb, n in specs], "object_type.chain.Chain_spec[]")
    u.put("ON", "switch.LJ_truncate")
    u.put(1.0, "EPSILON")
    for path, value in puts.items():
        u.put(value, path.replace("__", "."))
    u.write(str(tmp_path / "chain.udf"))
    return str(tmp_path / "chain.udf")



# ---------------------------------------------------------------- from test_dipoles.py
EX12_DATA = os.path.join(TESTS, "data", "ex12")


def nowall_input(tmp_path, name="in.udf", **puts):
    copy_schema(tmp_path, EX12_DATA)
    u = UDFManager(os.path.join(EX12_DATA, "nowall.udf"))
    for path, value in puts.items():
        u.put(value, path.replace("__", "."))
    u.write(str(tmp_path / name))
    return str(tmp_path / name)



# ---------------------------------------------------------------- from test_janus.py
def _sample(tmp_path, old, new):
    copy_schema(tmp_path)
    text = open(os.path.join(SAMPLES, "input.udf")).read()
    for o, n in zip(old, new):
        assert o in text, o
        text = text.replace(o, n, 1)
    p = tmp_path / "input.udf"
    p.write_text(text)
    return str(p)


SPECS = ('[{8,1.00000000000000,0.0,"NONE","OFF",{0.0,0.0,0.0}{0.0,0.0,0.0}0.0,0.0}]',
         '[{2,1.0,0.0,"Y","SQUIRMER",{0.0,0.0,0.0}{0.0,0.0,0.0}0.02,-1.0}'
         '{1,1.0,0.0,"X","TUMBLER",{0.01,0.0,0.0}{0.0,0.5,0.0}0.0,0.0}'
         '{1,1.0,0.0,"NONE","OBSTACLE",{0.0,0.0,0.0}{0.0,0.0,0.0}0.0,0.0}]')


def janus_input(d, eq="Navier_Stokes", nsnap=2, rotation="ON"):
    from udf import UDFManager
    os.makedirs(d, exist_ok=True)
    path = _sample(d, [SPECS[0]], [SPECS[1]])
    u = UDFManager(path)
    u.put(eq, "constitutive_eq.type")
    for k in ("NPX", "NPY", "NPZ"):
        u.put(5, f"mesh.{k}")
    u.put(0.5, "constitutive_eq.Navier_Stokes.kBT")
    u.put("random", "switch.INIT_orientation")
    u.put(rotation, "switch.ROTATION")
    u.put(1e-3, "switch.SLIP_tol")
    u.put(3, "switch.SLIP_iter")
    u.put(2, "output.GTS")
    u.put(nsnap, "output.Num_snap")
    u.write(path)
    return path



# ---------------------------------------------------------------- from test_mpi.py
def _mpiexec():
    try:
        import mpi4py  # noqa: F401
    except ImportError:
        return None
    here = os.path.dirname(sys.executable)
    return shutil.which("mpiexec", path=here) or shutil.which("mpiexec")


MPIEXEC = _mpiexec()


def mpirun(d, n, inp, *extra, check=True):
    cmd = [MPIEXEC, "-n", str(n), sys.executable, "-m", "kapsel.cli", f"-I{inp}",
           "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--seed", "11", "--quiet", *extra]
    r = subprocess.run(cmd, cwd=d, capture_output=True, text=True, timeout=600)
    if check:
        assert r.returncode == 0, r.stderr[-3000:]
    return r


def agree_with_serial(serial, make, label, limit, extra=None,
                      moved=lambda diff: max(diff.values()) > 0):
    """Run the input ``make(n)`` writes (its directory returned) on 1, 2 (slabs) and 4
    (2 x 2) ranks and compare with the serial run in ``serial``: 1 rank bit-identical, 2
    and 4 within round-off (max |difference| < ``limit``) and ``moved(diff)`` (the sums
    really ran in another order); ``extra(d)``: more differences (name -> value) to print
    and bound."""
    for n, grid in ((1, ()), (2, ()), (4, ("-X2", "-Y2"))):
        d = make(n)
        mpirun(d, n, "input.udf", *grid)
        diff = differences(str(serial), str(d))
        if extra is not None:
            diff.update(extra(d))
        print(f"{label}, {n} rank(s): max |distributed - serial| {max(diff.values()):.3g} "
              f"({max(diff, key=diff.get)}); {diff}")
        if n == 1:
            assert max(diff.values()) == 0.0, diff
        else:
            assert max(diff.values()) < limit, diff
            assert moved(diff), diff


def differences(a, b):
    """max |a - b| over the restart data (and state file) and the output records."""
    sa, sb = saved_data(os.path.join(a, "restart.udf")), saved_data(os.path.join(b, "restart.udf"))
    assert set(sa) == set(sb)
    out = {}
    for k in sa:
        if k == "state:accumulators":             # sums kept between records (JSON)
            import json
            xa, xb = (np.array(json.loads(x)["stress"] if "stress" in json.loads(x)
                               else json.loads(x)["zigzag"], dtype=float) for x in (sa[k], sb[k]))
            np.testing.assert_allclose(xb, xa, rtol=1e-9, err_msg=k)
        elif isinstance(sa[k], str):
            assert sa[k] == sb[k], k
        elif sa[k].dtype.kind in "fc":
            out[k] = float(np.abs(sa[k] - sb[k]).max())
        else:
            assert np.array_equal(sa[k], sb[k]), k
    ra, rb = records(os.path.join(a, "output.udf")), records(os.path.join(b, "output.udf"))
    assert len(ra) == len(rb)
    assert [t for t, _ in ra] == [t for t, _ in rb]
    out["records"] = max(float(np.abs(np.asarray(pa) - np.asarray(pb)).max())
                         for (_, pa), (_, pb) in zip(ra, rb))
    return out


def continue_distributed(d, n, snaps):
    """Continue the run in ``d`` from its restart.udf up to ``snaps`` snapshots, on ``n``
    ranks (0: serially in this process)."""
    rs = UDFManager(str(d / "restart.udf"))
    rs.put(snaps, "output.Num_snap")
    rs.write(str(d / "cont.udf"))
    shutil.copy(state_path(str(d / "restart.udf")), state_path(str(d / "cont.udf")))
    if n:
        mpirun(d, n, "cont.udf")
    else:
        assert cli(d, "cont.udf") == 0



# ---------------------------------------------------------------- from test_spm_validation.py
A, XI = 4.0, 2.0      # the SPM validations' sphere: radius, interface thickness


def measured_dt(factor, rho, eta, dx):
    """The time step these measurements were made at: factor RHO / (ETA (pi / DX)^2).  (Not
    the automatic time step of a run, kapsel.timestep.auto_dt; a fixed dt keeps the tables
    in the comments valid.)"""
    return factor * rho / (eta * (np.pi / dx) ** 2)


def _spectral(L, dt, fix_cell, threads=1):
    import pytest
    grid_mod = pytest.importorskip("kapsel.mesh.grid")
    spectral = pytest.importorskip("kapsel.fluid.spectral")
    grid = grid_mod.Grid((L, L, L), 1.0, threads=threads)
    return spectral.SpectralNS(grid, 1.0, 1.0, dt, fix_cell=(fix_cell,) * 3)


def _auto_dt(factor=1.0):
    return measured_dt(factor, 1.0, 1.0, 1.0)


# The SPM drag depends on nu dt / xi^2 (the rigidity is imposed once per step, so the
# interface is the more rigid the smaller dt): measured with a Stokes spectral stand-in at
# L = 32, V / V_Hasimoto = 1.055, 1.001, 0.962, 0.924 and Omega / Omega_theory = 1.076,
# 0.981, 0.914, 0.849 for dt = 0.101 (measured_dt(1)), 0.05, 0.025, 0.01.  The validation runs
# use measured_dt(0.5).
DT_FACTOR = 0.5


def _spheres(R, mass_ratio=1.0):
    R = np.asarray(R, dtype=float)
    p = ParticleState.spheres([0] * len(R), [A] * len(R), [mass_ratio] * len(R), 1.0)
    p.R[:] = R
    p.R_raw[:] = R
    return p


def _hasimoto_K(L):
    c = 4 / 3 * np.pi * A ** 3 / L ** 3
    return 1.0 / (1 - 1.7601 * c ** (1 / 3) + c - 1.5593 * c ** 2 + 3.9799 * c ** (8 / 3)
                  - 3.0734 * c ** (10 / 3))


def exchanged_momentum(spm, dv, dw):
    """sum_i [RHO V_p,i dV_i + RHO dOmega_i x m_i - M_i dV_i]: the fluid momentum the
    particles' step adds when their velocities change by dv, dw (``_momentum_balance``)."""
    dx3, p = spm.dx ** 3, spm.p
    vp = spm.w.sum(axis=1) * dx3
    m1 = np.einsum("ns,nsk->nk", spm.w, spm.r) * dx3
    return (spm.rho * vp[:, None] * dv + spm.rho * np.cross(dw, m1)
            - p.mass[:, None] * dv).sum(axis=0)


def run_until_steady(spm, value, n_steps, t_max, tol):
    """Advance ``spm`` ``n_steps`` at a time until ``value()`` changes by less than ``tol``
    relatively over one such block, or its time reaches ``t_max``."""
    prev = None
    while spm.step_index * spm.dt < t_max:
        spm.run(n_steps)
        v = value()
        if prev is not None and abs(v - prev) < tol * abs(v):
            break
        prev = v


def terminal_velocity(L, dt=None, tol=5e-4, t_max=None, threads=1):
    """Sphere A = 4 under F = (1, 0, 0), FIX_CELL on: V_x / (F / (6 pi eta A K)) at steady state
    (stop when V changes by < tol relatively over one slowest-mode decay time L^2/(4 pi^2))."""
    dt = dt or _auto_dt(DT_FACTOR)
    fluid = _spectral(L, dt, fix_cell=True, threads=threads)
    p = _spheres([[L / 2 + 0.3, L / 2 + 0.2, L / 2 - 0.3]])
    F = np.array([[1.0, 0.0, 0.0]])
    spm = SPM(fluid, p, A, XI, 1.0, 1.0, dt, forces=lambda q: (F, np.zeros((1, 3))))
    U = 1.0 / (6 * np.pi * A * _hasimoto_K(L))
    tau = L ** 2 / (4 * np.pi ** 2)
    n_tau = max(1, int(round(tau / dt)))
    run_until_steady(spm, lambda: p.v[0, 0], n_tau, t_max or 12 * tau, tol)
    return p.v[0] / U, spm.step_index * dt


# ---------------------------------------------------------------- from test_bad_input.py
# The bad-input corpus (tests/bad_inputs/, made by its make_corpus.py): what each file breaks
# and what the one line that refuses it says; the run (test_bad_input) and --check
# (test_check_banner) refuse every one of them.
CORPUS_DIR = os.path.join(TESTS, "bad_inputs")
CORPUS_FLAGS = ["-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf"]

# file -> (what is wrong, fragments the one-line message must contain, command-line changes)
CORPUS = {
    # --- syntax: truncated, unbalanced, garbage (file:line[:col])
    "truncated_mid_value.udf": ("file ends inside the string \"12:6\" of LJ_powers",
                                ["truncated_mid_value.udf:24:11:", "end of file inside a string"]),
    "truncated_mid_number.udf": ("file ends in the middle of the number A_XI:2.00000",
                                 ["truncated_mid_number.udf:20:", "unexpected end of file"]),
    "truncated_mid_block.udf": ("file ends inside the switch:{...} block",
                                ["truncated_mid_block.udf:36:", "unexpected end of file",
                                 "not closed"]),
    "missing_end_data.udf": ("\\end{data} removed",
                             ["missing_end_data.udf:109:", "unexpected end of file"]),
    "missing_data_block.udf": ("only the header and the include: no \\begin{data} block",
                               ["missing_data_block.udf:", "no \\begin{data}"]),
    "unbalanced_brace.udf": ("an extra closing brace: mesh:{4,4,4}}",
                             ["unbalanced_brace.udf:25:13:", "unexpected '}'"]),
    "empty_file.udf": ("an empty file", ["empty_file.udf:", "is not a KAPSEL input",
                                         'include{"define.udf"}']),
    "binary_garbage.udf": ("binary bytes instead of text",
                           ["binary_garbage.udf:1:1:", "binary data"]),
    "nan_value.udf": ("A:NaN (not a UDF number)", ["nan_value.udf:21:3:", "unexpected 'NaN'"]),
    # --- wrong types
    "string_for_float.udf": ('A:"four", a string where a double goes',
                             ["string_for_float.udf:21:3:", "expected a number", '"four"',
                              "(at A)"]),
    "float_for_int_mesh.udf": ("mesh:{4,4.5,4}, a float where an int goes",
                               ["float_for_int_mesh.udf:25:9:", "expected an integer", "4.5",
                                "mesh.NPY"]),
    "float_for_int_gts.udf": ("output.GTS = 1.5",
                              ["float_for_int_gts.udf:56:9:", "expected an integer",
                               "output.GTS"]),
    "number_for_select.udf": ("LJ_powers:12, a number where a select string goes",
                              ["number_for_select.udf:24:11:", "expected one of 12:6",
                               "(at LJ_powers)"]),
    "string_for_int_particles.udf": ('Particle_number "two"',
                                     ["string_for_int_particles.udf:11:5:", '"two"',
                                      "Particle_spec[0].Particle_number"]),
    "too_few_values.udf": ("gravity:{0.0}, one of its two values missing",
                           ["too_few_values.udf:22:9:", "expected 2 values", "found 1",
                            "(at gravity)"]),
    "int_infinite.udf": ("output.GTS = 1e400 (an int that overflows to infinity)",
                         ["int_infinite.udf:56:9:", "expected an integer, found 1e400",
                          "output.GTS"]),
    "int_out_of_range.udf": ("Particle_number 99999999999, beyond a UDF (32-bit) int",
                             ["int_out_of_range.udf:11:5:", "99999999999 is out of range",
                              "Particle_number"]),
    "unknown_item.udf": ("EPSILLON:5.0, a misspelt item",
                         ["unknown_item.udf:23:1:", "'EPSILLON' is not defined",
                          "did you mean 'EPSILON'"]),
    "missing_item.udf": ("the line A:4.0 deleted (it used to read as A = 0)",
                         ["missing_item.udf:", "A:", "is missing"]),
    "duplicate_item.udf": ("A given twice (the second used to win silently)",
                           ["duplicate_item.udf:22:1:", "'A' is given twice",
                            "first at line 21"]),
    # --- unknown or unsupported select values
    "unknown_constitutive_eq.udf": ("constitutive_eq type \"Navier_Stokes_Cahn_Hilliard\"",
                                    ["unknown_constitutive_eq.udf:7:18:",
                                     "unknown choice 'Navier_Stokes_Cahn_Hilliard'",
                                     "Navier_Stokes_Cahn_Hilliard_FDM",
                                     "(at constitutive_eq.type)"]),
    "electrolyte_zero_charge.udf": ("constitutive_eq type Electrolyte with uncharged "
                                    "particles (Surface_charge 0, the original exits)",
                                    ["electrolyte_zero_charge.udf:11:24:",
                                     "Surface_charge = 0.0", "must be non-zero"]),
    "bad_lj_powers.udf": ('LJ_powers:"12:7"',
                          ["bad_lj_powers.udf:24:11:", "unknown choice '12:7'", "36:18",
                           "(at LJ_powers)"]),
    "unknown_time_increment.udf": ('time_increment type "fixed"',
                                   ["unknown_time_increment.udf:26:17:",
                                    "unknown choice 'fixed'", "auto, manual"]),
    "unknown_g_direction.udf": ('gravity G_direction "+Y"',
                                ["unknown_g_direction.udf:22:14:", "unknown choice '+Y'",
                                 "gravity.G_direction"]),
    # --- includes
    "missing_include.udf": ('\\include{"defines.udf"}, a file that does not exist',
                            ["missing_include.udf:3:10:", '"defines.udf" not found']),
    "include_not_udf.udf": ("\\include of a plain text file (notes.txt)",
                            ["notes.txt:1:1:", "is this a UDF file?",
                             "included from include_not_udf.udf:3"]),
    "include_cycle.udf": ("the file includes itself",
                          ["include_cycle.udf", "include cycle"]),
    # --- impossible meshes
    "mesh_npx_zero.udf": ("NPX = 0", ["mesh_npx_zero.udf:25:7:", "mesh.NPX = 0",
                                      "at least 1"]),
    "mesh_npy_negative.udf": ("NPY = -2", ["mesh_npy_negative.udf:25:9:", "mesh.NPY = -2",
                                           "at least 1"]),
    "mesh_npz_too_large.udf": ("NPZ = 40 (2^40 points on one side)",
                               ["mesh_npz_too_large.udf:25:11:", "mesh.NPZ = 40",
                                "too large"]),
    "mesh_memory_absurd.udf": ("mesh {12,12,11}: 2^35 points, terabytes of memory",
                               ["mesh_memory_absurd.udf:25:6:", "mesh = [12, 12, 11]",
                                "4096 x 4096 x 2048", "TB of memory", "more than"]),
    "mesh_dx_zero.udf": ("DX = 0", ["mesh_dx_zero.udf:7:1037:",
                                    "Navier_Stokes_Cahn_Hilliard_FDM.DX = 0.0", "positive"]),
    # --- fluid and solvers
    "eta_negative.udf": ("ETA = -1", ["eta_negative.udf:7:1071:",
                                      "Navier_Stokes_Cahn_Hilliard_FDM.ETA = -1.0",
                                      "positive"]),
    "rho_zero.udf": ("RHO = 0", ["rho_zero.udf:7:1054:",
                                 "Navier_Stokes_Cahn_Hilliard_FDM.RHO = 0.0", "positive"]),
    "kbt_negative.udf": ("kBT = -0.5", ["kbt_negative.udf:7:1088:",
                                        "Navier_Stokes_Cahn_Hilliard_FDM.kBT = -0.5",
                                        "zero or positive"]),
    "eta_infinite.udf": ("ETA = 1e400 (overflows to infinity)",
                         ["eta_infinite.udf:7:", "1e400 is beyond the range of a double",
                          "Navier_Stokes_Cahn_Hilliard_FDM.ETA"]),
    "tolerance_positive.udf": ("CH_solver tolerance 9 (it is a base-10 exponent)",
                               ["tolerance_positive.udf:7:1013:",
                                "CH_solver.implicit_scheme.tolerance = 9.0",
                                "base-10 exponent", "negative"]),
    "tolerance_unreachable.udf": ("CH_solver tolerance exponent -300 (10^-300: never reached)",
                                  ["tolerance_unreachable.udf:7:1013:", "tolerance = -300.0",
                                   "below -15"]),
    "dx_huge_auto_dt_zero.udf": ("DX = 1e300: beyond any physical size (the automatic dt "
                                 "would underflow to 0)",
                                 ["dx_huge_auto_dt_zero.udf:7:", "DX = 1e+300",
                                  "between 1e-30 and 1e+30"]),
    "maximum_iteration_zero.udf": ("CH_solver maximum_iteration 0",
                                   ["maximum_iteration_zero.udf:7:1031:",
                                    "implicit_scheme.maximum_iteration = 0", "at least 1"]),
    # --- time and output
    "factor_negative.udf": ("time_increment auto factor -1",
                            ["factor_negative.udf:26:25:", "time_increment.auto.factor = -1.0",
                             "positive"]),
    "delta_t_zero.udf": ("time_increment manual delta_t 0",
                         ["delta_t_zero.udf:26:45:", "time_increment.manual.delta_t = 0.0",
                          "positive"]),
    "delta_t_unstable.udf": ("manual delta_t 100, far past the explicit scheme's limit",
                             ["delta_t_unstable.udf:26:1:", "time_increment = 100.0",
                              "stability limit"]),
    "gts_zero.udf": ("GTS = 0", ["gts_zero.udf:56:9:", "output.GTS = 0", "at least 1"]),
    "num_snap_negative.udf": ("Num_snap = -3", ["num_snap_negative.udf:56:11:",
                                                "output.Num_snap = -3", "at least 1"]),
    "num_snap_zero.udf": ("Num_snap = 0 (a run of no steps)",
                          ["num_snap_zero.udf:56:11:", "output.Num_snap = 0", "at least 1"]),
    # --- particles
    "a_zero.udf": ("A = 0", ["a_zero.udf:21:3:", "A = 0.0", "positive"]),
    "a_xi_negative.udf": ("A_XI = -2", ["a_xi_negative.udf:20:6:", "A_XI = -2.0",
                                        "positive"]),
    "mass_ratio_zero.udf": ("MASS_RATIO = 0", ["mass_ratio_zero.udf:11:7:",
                                               "Particle_spec[0].MASS_RATIO = 0.0",
                                               "positive"]),
    "particle_number_negative.udf": ("Particle_number = -1",
                                     ["particle_number_negative.udf:11:5:",
                                      "Particle_spec[0].Particle_number = -1"]),
    "particle_larger_than_box.udf": ("A = 9 in a 16^3 box",
                                     ["particle_larger_than_box.udf:21:3:", "A = 9.0",
                                      "does not fit in the box 16 x 16 x 16"]),
    "too_many_particles.udf": ("200 particles of radius 4 in a 16^3 box",
                               ["too_many_particles.udf:8:13:", "200 particles",
                                "cannot fit"]),
    "user_specify_missing_data.udf": ("INIT_distribution user_specify with no entries for 2 "
                                      "particles",
                                      ["user_specify_missing_data.udf:34:4:",
                                       "user_specify.Particles[] = 0",
                                       "one entry per particle"]),
    "user_specify_too_few.udf": ("user_specify with 1 entry for 2 particles",
                                 ["user_specify_too_few.udf:34:4:",
                                  "user_specify.Particles[] = 1", "one entry per particle"]),
    "user_specify_overlap.udf": ("user_specify particles 1 apart with A = 4 (it used to "
                                 "write the first snapshot, then stop)",
                                 ["user_specify_overlap.udf:34:4:", "particles 0 and 1",
                                  "they overlap"]),
    "pin_without_particles.udf": ("Particle_number 0 but switch.pin YES pins particle 2",
                                  ["pin_without_particles.udf:44:4:",
                                   "switch.pin.YES.pin[] = [2]", "has none"]),
    "pin_id_out_of_range.udf": ("pin of particle 5 with 2 particles",
                                ["pin_id_out_of_range.udf:44:4:", "switch.pin.YES.pin[] = [5]",
                                 "0..1"]),
    "random_walk_negative.udf": ("INIT_distribution random_walk with iteration -100",
                                 ["random_walk_negative.udf:32:4:",
                                  "random_walk.iteration = -100"]),
    # --- several problems at once: one line each, at the value itself
    "several_problems.udf": ("mesh NPX 0, A 0 and GTS 0 in one file: all three reported",
                             ["several_problems.udf:25:7: mesh.NPX = 0",
                              "several_problems.udf:21:3: A = 0.0",
                              "several_problems.udf:56:9: output.GTS = 0"]),
    "unsupported_together.udf": ("TUMBLER janus particles in an Electrolyte run with "
                                 "uncharged particles: every problem at once, one line each "
                                 "(self-propelled particles need Navier_Stokes or "
                                 "Shear_Navier_Stokes, as in the original)",
                                 ["unsupported_together.udf:11:24:", "Surface_charge = 0.0",
                                  "unsupported_together.udf:11:35:",
                                  "janus_propulsion = 'TUMBLER'",
                                  "need constitutive_eq Navier_Stokes or Shear_Navier_Stokes"]),
    # --- resume
    "continue_without_saved_data.udf": ("resume CONTINUE_FDM_PHASE_SEPARATION in a fresh "
                                        "input (no saved data)",
                                        ["continue_without_saved_data.udf:57:1:",
                                         "resume.CONTINUE_FDM_PHASE_SEPARATION",
                                         "holds no saved state", "NEW"]),
    # --- command line: a valid input, bad flags
    "cli_define_missing.udf": ("-D names a file that does not exist",
                               ["-Dnosuch_define.udf", "no such file"],
                               ["-Dnosuch_define.udf"]),
    "cli_define_not_a_schema.udf": ("-D names a UDF without the KAPSEL schema "
                                    "(it used to write output.udf, then crash)",
                                    ["-Dkapsel_unit.udf", "not a KAPSEL define file",
                                     "lack E, t"], ["-Dkapsel_unit.udf"]),
    "cli_output_dir_missing.udf": ("-O in a directory that does not exist",
                                   ["-Onodir/output.udf", "nodir does not exist"],
                                   ["-Onodir/output.udf"]),
    "cli_output_dir_is_a_file.udf": ("-O below a plain file (not a directory)",
                                     ["-Onotes.txt/output.udf", "is not a directory"],
                                     ["-Onotes.txt/output.udf"]),
    "cli_restart_dir_missing.udf": ("-R in a directory that does not exist (it used to "
                                    "write output.udf and the fields, then crash)",
                                    ["-Rnodir/restart.udf", "nodir does not exist"],
                                    ["-Rnodir/restart.udf"]),
}


def bad_input_dir(d, name):
    """A run directory: the corpus file, the sample's schema files and notes.txt."""
    if CORPUS_DIR not in sys.path:
        sys.path.insert(0, CORPUS_DIR)
    import make_corpus
    copy_schema(d)
    for f in make_corpus.SUPPORT:
        shutil.copy(os.path.join(CORPUS_DIR, f), d / f)
    shutil.copy(os.path.join(CORPUS_DIR, name), d / name)


def bad_input_command(name):
    """The command line of the corpus input ``name`` (its own flags where CORPUS gives them)."""
    entry = CORPUS[name]
    flags = list(CORPUS_FLAGS)
    for arg in (entry[2] if len(entry) > 2 else []):
        flags = [f for f in flags if f[:2] != arg[:2]] + [arg]
    return [f"-I{name}"] + flags
