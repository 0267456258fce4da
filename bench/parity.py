"""kapsel-py against the original program, run side by side on the same document (issue 24).

    .venv/bin/python bench/parity.py [--original PATH] [--kref DIR] [--scene NAME ...]
                                     [--steps N] [--keep DIR] [--json FILE] [--list]
                                     [--cache DIR]

Every scene is deterministic (kBT 0, manual dt, user_specify positions and orientations, no
initial concentration noise), built from the fixture ``samples/kapsel-udf/ex14`` (its
define.udf, version 4.1, declares every section: walls, dipoles, Quincke, janus, the CH surface
terms) by path=value edits.  Both programs read the same document: kapsel-py the UDF text,
the original the flattened form its kref stand-in for OCTA's UDFManager reads (made by kref's
``flatten_udf.py`` with kapsel-py's own reader).  Each program runs in its own directory,
one thread; then, per record (the same steps in both), against the original:

    dR/motion   max |R_py - R_orig| (minimum image) over the largest displacement of the run;
                '(f32)' when max |R_py - R_orig| is within one float32 ulp of max |R| (the
                records' resolution: a run that moves its particles less than ~1e-4 cannot
                show a difference there)
    dv/|v|      max |v_py - v_orig| over max |v_orig|
    dw/|w|      max |omega_py - omega_orig| over max |omega_orig| ('-' when the original's is 0)
    u L2, psi L2   relative L2 of the velocity field / order parameter at the last common
                snapshot (FDM types: velocity_<n>.h5, orderparam_<n>.h5 in both runs)

kapsel-py's records are single precision (OCTA's ``float`` items), so 1e-7 is the floor of
the first three columns.  Rigid bodies compare the bodies (``RigidParticles[]``).

The original is not part of the project (no licence): build it from its public source with
``../shared/kref/`` (its README: ``KREF=<dir> KAPSEL3_GIT=<git dir> ../shared/kref/build.sh``)
and give its binary by ``--original`` or ``$KREF_CPP``; the kref tools' directory by
``--kref`` or ``$KREF_TOOLS`` (default ``../shared/kref`` next to the repository).
With ``--cache DIR`` (or ``$KAPSEL_PARITY_CACHE``) the original's run of each document is kept
and reused (it does not change while kapsel-py does).  Not a test: CI has no original.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from udf import UDFManager  # noqa: E402

BASE = ROOT / "samples" / "kapsel-udf" / "ex14" / "input.udf"
US = "switch.INIT_distribution.user_specify.Particles[]"
TYPES = ("Navier_Stokes", "Shear_Navier_Stokes", "Shear_Navier_Stokes_Lees_Edwards",
         "Electrolyte", "Navier_Stokes_FDM", "Navier_Stokes_Cahn_Hilliard_FDM",
         "Shear_Navier_Stokes_Lees_Edwards_FDM", "Shear_NS_LE_CH_FDM")
FDM = {t for t in TYPES if t.endswith("FDM")}
CH = {"Navier_Stokes_Cahn_Hilliard_FDM", "Shear_NS_LE_CH_FDM"}


def row(R, v=(0, 0, 0), q=(1, 0, 0, 0), w=(0, 0, 0)):
    """One user_specify particle: R, v, q, omega."""
    return [float(x) for x in (*R, *v, *q, *w)]


def common(typ, n=5, dt=0.05, gts=10, objects="spherical_particle"):
    """Edits every scene shares: the type, a cube of 2^n, kBT 0, manual dt, no walls, no
    multipoles, no AVS, user_specify placement, FIX_CELL off, no concentration noise."""
    e = {"constitutive_eq.type": typ, "mesh.NPX": n, "mesh.NPY": n, "mesh.NPZ": n,
         f"constitutive_eq.{typ}.kBT": 0.0, "time_increment.type": "manual",
         "time_increment.manual.delta_t": dt, "output.GTS": gts, "output.AVS": "OFF",
         "output.UDF": "ON", "switch.wall.type": "NONE", "switch.multipole.type": "OFF",
         "switch.quincke.type": "OFF", "switch.INIT_distribution.type": "user_specify",
         "switch.INIT_orientation": "user_specify", "switch.pin.type": "NO",
         "switch.free_rigid.type": "NO", "switch.ROTATION": "ON", "switch.LJ_truncate": "ON",
         "LJ_powers": "12:6", "EPSILON": 1.0, "gravity.G": 0.0, "gravity.G_direction": "-Y",
         "A": 4.0, "A_XI": 2.0, "object_type.type": objects,
         "switch.FIX_CELL.x": "OFF", "switch.FIX_CELL.y": "OFF", "switch.FIX_CELL.z": "OFF"}
    if typ in CH:            # the manual's sample's free energy, no wall or surface terms
        lan = f"constitutive_eq.{typ}.Potential.Landau"
        e.update({f"{lan}.composition_ratio": 0.0, f"{lan}.a": 1.0, f"{lan}.b": 1.0,
                  f"{lan}.d": 1.0, f"{lan}.w": -1.0, f"{lan}.alpha": 1.0, f"{lan}.kappa": 1.0})
        if typ == "Navier_Stokes_Cahn_Hilliard_FDM":
            e.update({f"{lan}.w_wall": 0.0, f"{lan}.z": 0.0, f"{lan}.psi_0_p": 0.0,
                      f"{lan}.psi_0_wall.type": "uniform",
                      f"{lan}.psi_0_wall.uniform.psi_0_wall": 0.0, f"{lan}.psi_dry": 0.0})
        for pot in ("Landau", "Flory_Huggins"):
            e[f"constitutive_eq.{typ}.Potential.{pot}.initial_fluctuation"] = 0.0
    return e


def spheres(rows, mass=2.0, janus=None):
    """spherical_particle, one species: rows of row(); janus = (axis, propulsion, force,
    torque, slip_vel, slip_mode) or None."""
    s = "object_type.spherical_particle.Particle_spec[0]"
    e = {f"{s}.Particle_number": len(rows), f"{s}.MASS_RATIO": mass, US: rows,
         f"{s}.janus_axis": "NONE", f"{s}.janus_propulsion": "OFF"}
    if janus:
        axis, prop, force, torque, b1, mode = janus
        e.update({f"{s}.janus_axis": axis, f"{s}.janus_propulsion": prop,
                  f"{s}.janus_force": list(force), f"{s}.janus_torque": list(torque),
                  f"{s}.janus_slip_vel": b1, f"{s}.janus_slip_mode": mode})
    return e


def chain(rows, mass=2.0):
    s = "object_type.chain.Chain_spec[0]"
    return {"object_type.type": "chain", f"{s}.Beads_number": len(rows),
            f"{s}.Chain_number": 1, f"{s}.MASS_RATIO": mass, US: rows}


def rigid(rows, beads, bodies=1, mass=2.0, motion="free", V=(0, 0, 0), W=(0, 0, 0)):
    s = "object_type.rigid.Rigid_spec[0]"
    return {"object_type.type": "rigid", f"{s}.Beads_number": beads,
            f"{s}.Chain_number": bodies, f"{s}.MASS_RATIO": mass, f"{s}.Rigid_motion": motion,
            f"{s}.Rigid_velocity": list(V), f"{s}.Rigid_omega": list(W), US: rows}


def gravity(G=0.01, d="-Y"):
    return {"gravity.G": G, "gravity.G_direction": d}


def shear(typ, rate=0.01, ac=False, freq=0.0):
    p = f"constitutive_eq.{typ}.External_field"
    if ac:
        return {f"{p}.type": "AC", f"{p}.AC.Shear_rate": rate, f"{p}.AC.Frequency": freq}
    return {f"{p}.type": "DC", f"{p}.DC.Shear_rate": rate}


def solvers(typ, ns=None, ch=None):
    e = {}
    if ns:
        e[f"constitutive_eq.{typ}.NS_solver.type"] = ns
    if ch:
        e[f"constitutive_eq.{typ}.CH_solver.type"] = ch
    return e


def wall(axis="Y", dh=6):
    return {"switch.wall.type": "FLAT", "switch.wall.FLAT.axis": axis,
            "switch.wall.FLAT.DH": dh, "switch.wall.FLAT.LJ_Params": "AUTO"}


def dipoles(p0=2.0, axis="Z"):
    d = "switch.multipole.ON.Dipole"
    return {"switch.multipole.type": "ON", f"{d}.type": "ON", f"{d}.ON.magnitude": p0,
            f"{d}.ON.type": "FIXED", f"{d}.ON.FIXED.dir": axis}


def quincke_dipoles(pz, p0=6.0, K=20.0):
    """Two one-bead rollers in ex12's document (its define.udf has the QUINCKE dipoles),
    axes across the field (body x; the second turned 45 degrees about z), 8 apart."""
    d = "switch.multipole.ON.Dipole"
    return merge({"_base": ROOT / "tests" / "data" / "ex12" / "nowall.udf", "A": 2.0},
                 rigid([row((10.0, 16.0, 16.0)), row((18.0, 16.0, 16.0), q=Q45)], 1, bodies=2),
                 {"switch.quincke.type": "ON", "switch.quincke.ON.e_dir": "Z",
                  "switch.quincke.ON.w_dir": "X", "switch.quincke.ON.torque_amp": K,
                  "switch.multipole.type": "ON", f"{d}.type": "ON", f"{d}.ON.magnitude": p0,
                  f"{d}.ON.type": "QUINCKE", f"{d}.ON.QUINCKE.type": "no_mirror_image",
                  f"{d}.ON.QUINCKE.Pz_factor": pz})


def merge(*ds):
    out = {}
    for d in ds:
        out.update(d)
    return out


NS, FD, NSCH = "Navier_Stokes", "Navier_Stokes_FDM", "Navier_Stokes_Cahn_Hilliard_FDM"
SNS, LE = "Shear_Navier_Stokes", "Shear_Navier_Stokes_Lees_Edwards"
LEF, LECH, EL = "Shear_Navier_Stokes_Lees_Edwards_FDM", "Shear_NS_LE_CH_FDM", "Electrolyte"
SED = [row((16.0, 16.0, 16.0))]
PAIR48 = [row((18.0, 24.0, 24.0), v=(0.01, 0, 0)), row((30.0, 24.5, 24.0), v=(-0.01, 0, 0))]
REST2 = [row((16.0, 10.0, 16.0)), row((16.0, 22.0, 16.0))]        # 12 apart in y
# The FDM scenes start their particles at rest: with a non-zero initial particle velocity the
# original's FDM types start from the Fourier coefficients of the velocity field (its
# initialisation ends with U2zeta_k, sp_3d_ns.cxx:863, which transforms u in place, and the
# MAC solver then reads u as a real-space field: max|u| 6 for spheres at 0.006); kapsel-py
# starts from the real field.  The CH8 spheres settle (gravity) among the wetting fields.
CH8 = [row((8.0 + 16 * i, 8.0 + 16 * j, 8.0 + 16 * k)) for i in range(2) for j in range(2)
       for k in range(2)]
ROD = [row((12.0 + 4.0 * b, 16.0, 16.0)) for b in range(3)]        # 3 touching beads (A 2)
Q45 = (np.cos(np.pi / 8), 0.0, 0.0, np.sin(np.pi / 8))             # 45 degrees about z
QY = (np.cos(np.pi / 8), 0.0, np.sin(np.pi / 8), 0.0)              # 45 degrees about y
QY30 = (np.cos(np.pi / 12), 0.0, np.sin(np.pi / 12), 0.0)          # 30 degrees about y
ROLLERS = [row((10.0, 16.0, 16.0), q=QY), row((18.0, 16.0, 16.0), q=QY30)]  # 8 apart

# name: (label, edits, steps)
SCENES = {
    "ns_sed": ("Navier_Stokes, 1 sphere sedimenting", merge(common(NS), spheres(SED), gravity()), 200),
    "ns_sed_fixcell": ("Navier_Stokes, 1 sphere sedimenting, FIX_CELL", merge(
        common(NS), spheres(SED), gravity(),
        {"switch.FIX_CELL.x": "ON", "switch.FIX_CELL.y": "ON", "switch.FIX_CELL.z": "ON"}), 200),
    "ns_spin": ("Navier_Stokes, 1 sphere spun up (omega_z 0.01)", merge(
        common(NS), spheres([row((16.0, 16.0, 16.0), w=(0, 0, 0.01))])), 200),
    "ns_lj48": ("Navier_Stokes 64^3 (LJ cells right from 48), 2 spheres colliding", merge(
        common(NS, n=6), spheres(PAIR48), {"EPSILON": 1.0}), 200),
    # LJ_truncate OFF where the half-box cap binds (A 8: min(64 / 2, 2.5 x 16) = 32 = 2 sigma),
    # settling 28 apart in x and in y (39.6, minimum image): within the uncapped 2.5 sigma = 40,
    # beyond the cap
    "ns_lj_off_cap": ("Navier_Stokes 64^3, LJ_truncate OFF cut at half the box, 2 spheres", merge(
        common(NS, n=6), {"A": 8.0, "A_XI": 2.0, "switch.LJ_truncate": "OFF", "EPSILON": 50.0},
        spheres([row((18.0, 18.0, 32.0)), row((46.0, 46.0, 32.0))]), gravity()), 200),
    "ns_chain": ("Navier_Stokes 64^3, FENE chain of 4 beads sedimenting", merge(
        common(NS, n=6, objects="chain"), {"A": 2.0},
        chain([row((26.0 + 4.2 * b, 32.0, 32.0)) for b in range(4)]), gravity()), 200),
    "ns_pin": ("Navier_Stokes, 1 pinned sphere + 1 settling", merge(
        common(NS), spheres([row((10.0, 16.0, 16.0)), row((22.0, 20.0, 16.0))]), gravity(),
        {"switch.pin.type": "YES", "switch.pin.YES.pin[]": [0], "switch.pin.YES.pin_rot[]": []}), 200),
    "ns_wall": ("Navier_Stokes, flat wall (Y), 1 sphere settling on it", merge(
        common(NS), spheres([row((16.0, 14.0, 16.0))]), gravity(), wall()), 200),
    # p0 20 and the second dipole tilted 45 degrees (p0 2, both along z, moved them 5.5e-5 in
    # 200 steps: below the single-precision records' resolution of R near 16, 1.9e-6, so
    # dR/motion read 2.4e-2 while v and omega agreed to 3e-7)
    "ns_dipoles": ("Navier_Stokes, 2 FIXED dipoles (Z, one tilted 45 deg), p0 20", merge(
        common(NS), spheres([row((16.0, 16.0, 11.0)), row((17.0, 16.0, 21.0), q=QY)]),
        dipoles(p0=20.0)), 400),
    "ns_rigid_rod": ("Navier_Stokes, free rigid rod (3 beads) settling", merge(
        common(NS, objects="rigid"), {"A": 2.0}, rigid(ROD, 3), gravity()), 200),
    "ns_rigid_fix": ("Navier_Stokes, fixed rigid rod moving at V, Omega", merge(
        common(NS, objects="rigid"), {"A": 2.0},
        rigid(ROD, 3, motion="fix", V=(0.002, 0, 0), W=(0, 0, 0.001))), 200),
    "ns_rigid_start": ("Navier_Stokes, free rigid rod started with V, Omega, q", merge(
        common(NS, objects="rigid"), {"A": 2.0},
        rigid([row(r[:3], q=Q45) for r in ROD], 3, V=(0.002, 0, 0), W=(0, 0, 0.001))), 200),
    # torque_amp 20, both rollers tilted out of the plane across the field (torque_amp 0.5 and
    # the second roller's axis already across it moved them 1.8e-5: below the records'
    # resolution of R, dR/motion 4.5e-2 while v and omega agreed to 1e-7)
    "ns_quincke": ("Navier_Stokes, 2 one-bead Quincke rollers (tilted 45, 30 deg), K 20", merge(
        common(NS, objects="rigid"), {"A": 2.0}, rigid(ROLLERS, 1, bodies=2),
        {"switch.quincke.type": "ON", "switch.quincke.ON.e_dir": "Z",
         "switch.quincke.ON.w_dir": "X", "switch.quincke.ON.torque_amp": 20.0}), 200),
    # QUINCKE dipoles (the define.udf of tests/data/ex12 declares them; ex14's does not): two
    # rollers, axes across the field (x, and 45 degrees about z), 8 apart, p0 12
    "ns_quincke_dip": ("Navier_Stokes, 2 Quincke rollers, QUINCKE dipoles p0 12, K 20", merge(
        common(NS, objects="rigid"), quincke_dipoles(0.0, p0=12.0)), 200),
    # the same with Pz_factor 3: differs on purpose, the original's static part is
    # p0 Pz / |n x e| (md_force.cxx:22,26), kapsel-py's p0 Pz as its define.udf says
    # (docs/differences.md); the rollers' axes tilt under the dipole torques
    "ns_quincke_pz": ("ns_quincke_dip with Pz_factor 3 (differs: docs/differences.md)", merge(
        common(NS, objects="rigid"), quincke_dipoles(3.0)), 200),
    "ns_squirmer": ("Navier_Stokes, neutral squirmer (B1 0.01)", merge(
        common(NS), spheres(SED, mass=1.0, janus=("Z", "SQUIRMER", (0, 0, 0), (0, 0, 0), 0.01, 0.0)),
        {"switch.SLIP_tol": 1e-5, "switch.SLIP_iter": 20}), 200),
    "ns_pusher": ("Navier_Stokes, pusher squirmer (alpha -2)", merge(
        common(NS), spheres(SED, mass=1.0, janus=("Z", "SQUIRMER", (0, 0, 0), (0, 0, 0), 0.01, -2.0)),
        {"switch.SLIP_tol": 1e-5, "switch.SLIP_iter": 20}), 200),
    "ns_puller": ("Navier_Stokes, puller squirmer (alpha +2)", merge(
        common(NS), spheres(SED, mass=1.0, janus=("Z", "SQUIRMER", (0, 0, 0), (0, 0, 0), 0.01, 2.0)),
        {"switch.SLIP_tol": 1e-5, "switch.SLIP_iter": 20}), 200),
    "ns_tumbler": ("Navier_Stokes, tumbler (body force 0.05 z, torque 0.01 x)", merge(
        common(NS), spheres(SED, mass=1.0, janus=("Z", "TUMBLER", (0, 0, 0.05), (0.01, 0, 0), 0.0, 0.0))), 200),
    "fdm_e_sed": ("Navier_Stokes_FDM explicit, 1 sphere sedimenting", merge(
        common(FD), solvers(FD, ns="explicit_scheme"), spheres(SED), gravity()), 200),
    "fdm_i_sed": ("Navier_Stokes_FDM implicit, 1 sphere sedimenting", merge(
        common(FD), solvers(FD, ns="implicit_scheme"), spheres(SED), gravity()), 200),
    "fdm_dipoles": ("Navier_Stokes_FDM explicit, ns_dipoles' pair (p0 20, one tilted)", merge(
        common(FD), solvers(FD, ns="explicit_scheme"),
        spheres([row((16.0, 16.0, 11.0)), row((17.0, 16.0, 21.0), q=QY)]), dipoles(p0=20.0)), 400),
    "sns_dipoles": ("Shear_Navier_Stokes DC 0.01, ns_dipoles' pair (p0 20, one tilted)", merge(
        common(SNS), shear(SNS), spheres([row((16.0, 16.0, 11.0)), row((17.0, 16.0, 21.0), q=QY)]),
        dipoles(p0=20.0)), 400),
    "fdm_wall": ("Navier_Stokes_FDM explicit, flat wall (Y), 1 sphere settling", merge(
        common(FD), solvers(FD, ns="explicit_scheme"), spheres([row((16.0, 14.0, 16.0))]),
        gravity(), wall()), 200),
    "nsch_ee": ("NSCH_FDM NS explicit / CH explicit (dt 0.005), Landau, 8 spheres", merge(
        common(NSCH, dt=0.005), solvers(NSCH, ns="explicit_scheme", ch="explicit_scheme"), spheres(CH8), gravity()), 200),
    "nsch_ii": ("NSCH_FDM NS implicit / CH implicit, Landau, 8 spheres settling", merge(
        common(NSCH), solvers(NSCH, ns="implicit_scheme", ch="implicit_scheme"), spheres(CH8), gravity()), 200),
    "nsch_fh": ("NSCH_FDM, Flory-Huggins (0.5, chi 0.5), implicit CH, 8 spheres", merge(
        common(NSCH), solvers(NSCH, ns="explicit_scheme", ch="implicit_scheme"), spheres(CH8), gravity(),
        {f"constitutive_eq.{NSCH}.Potential.type": "Flory_Huggins"}), 200),
    "nsch_ex14": ("NSCH_FDM with ex14's surface terms (d 15, psi_0_p 0.1), 8 spheres", merge(
        common(NSCH), spheres(CH8), gravity(), {
            f"constitutive_eq.{NSCH}.Potential.Landau.{k}": v for k, v in (
                ("composition_ratio", -0.7), ("d", 15.0), ("alpha", 2.0), ("psi_0_p", 0.1),
                ("psi_0_wall.uniform.psi_0_wall", 1.0), ("w", 0.0))}), 200),
    # nsch_ex14 without what the original gets wrong there (docs/physics-walls-shear.md): with
    # no wall it still holds x >= L/2 as a wall (psi_0_wall, psi_0_p: wall.cxx:93-105), and its
    # first implicit NS step extrapolates psi from an unset psi^(-1) (2 psi^0: fdm.cxx:89)
    "nsch_surf": ("NSCH_FDM, ex14's d 15, alpha 2, composition -0.7 (psi_0 0), NS explicit", merge(
        common(NSCH), solvers(NSCH, ns="explicit_scheme", ch="implicit_scheme"), spheres(CH8),
        gravity(), {f"constitutive_eq.{NSCH}.Potential.Landau.{k}": v for k, v in (
            ("composition_ratio", -0.7), ("d", 15.0), ("alpha", 2.0), ("w", 0.0))}), 200),
    "nsch_wall": ("NSCH_FDM explicit / implicit, flat wall (Y) wetted (w_wall -1), 2 spheres", merge(
        common(NSCH), solvers(NSCH, ns="explicit_scheme", ch="implicit_scheme"), wall(),
        spheres([row((10.0, 14.0, 16.0)), row((22.0, 18.0, 16.0))]), gravity(),
        {f"constitutive_eq.{NSCH}.Potential.Landau.w_wall": -1.0}), 200),
    # nsch_wall with the explicit Cahn-Hilliard scheme, which wets the wall's faces everywhere
    # as kapsel-py does; what differs is the original's penalty on the half of the solid next
    # to lo only (docs/physics-walls-shear.md)
    "nsch_wall_ee": ("NSCH_FDM explicit / explicit (dt 0.005), flat wall (Y) wetted (w_wall -1), 2 spheres", merge(
        common(NSCH, dt=0.005), solvers(NSCH, ns="explicit_scheme", ch="explicit_scheme"), wall(),
        spheres([row((10.0, 14.0, 16.0)), row((22.0, 18.0, 16.0))]), gravity(),
        {f"constitutive_eq.{NSCH}.Potential.Landau.w_wall": -1.0}), 400),
    "nsch_visc": ("NSCH_FDM implicit, viscosity_change ETA_A 1 / ETA_B 5", merge(
        common(NSCH), solvers(NSCH, ns="implicit_scheme", ch="implicit_scheme"), spheres(CH8), gravity(),
        {f"constitutive_eq.{NSCH}.NS_solver.implicit_scheme.viscosity_change": "ON",
         f"constitutive_eq.{NSCH}.NS_solver.implicit_scheme.ON.ETA_A": 1.0,
         f"constitutive_eq.{NSCH}.NS_solver.implicit_scheme.ON.ETA_B": 5.0}), 200),
    "nsch_wetted": ("NSCH_FDM, 1 static wetted sphere (pinned, w -1)", merge(
        common(NSCH), solvers(NSCH, ns="explicit_scheme", ch="implicit_scheme"), spheres(SED),
        {f"constitutive_eq.{NSCH}.Potential.Landau.w": -1.0,
         "switch.pin.type": "YES", "switch.pin.YES.pin[]": [0], "switch.pin.YES.pin_rot[]": [0]}), 200),
    "zz_dc": ("Shear_Navier_Stokes DC 0.01, 2 spheres at rest", merge(
        common(SNS), spheres(REST2, mass=1.0), shear(SNS)), 200),
    "zz_ac": ("Shear_Navier_Stokes AC 0.01 f 0.002, 2 spheres", merge(
        common(SNS), spheres(REST2, mass=1.0), shear(SNS, ac=True, freq=0.002)), 200),
    "zz_chain": ("Shear_Navier_Stokes DC 64^3, FENE chain", merge(
        common(SNS, n=6, objects="chain"), {"A": 2.0}, shear(SNS),
        chain([row((26.0 + 4.2 * b, 24.0, 32.0)) for b in range(4)], mass=1.0)), 200),
    "le_dc": ("Lees-Edwards spectral DC 0.01, 2 spheres at rest", merge(
        common(LE), spheres(REST2, mass=1.0), shear(LE)), 200),
    "le_ac": ("Lees-Edwards spectral AC 0.01 f 0.002, 2 spheres", merge(
        common(LE), spheres(REST2, mass=1.0), shear(LE, ac=True, freq=0.002)), 200),
    "le_rigid": ("Lees-Edwards spectral DC, free rigid rod", merge(
        common(LE, objects="rigid"), {"A": 2.0}, shear(LE), rigid(ROD, 3, mass=1.0)), 200),
    "lef_e": ("Lees-Edwards FDM explicit DC 0.01, 2 spheres at rest", merge(
        common(LEF), solvers(LEF, ns="explicit_scheme"), spheres(REST2, mass=1.0), shear(LEF)), 200),
    "lef_i": ("Lees-Edwards FDM implicit DC 0.01, 2 spheres at rest", merge(
        common(LEF), solvers(LEF, ns="implicit_scheme"), spheres(REST2, mass=1.0), shear(LEF)), 200),
    "lech_ee": ("Shear_NS_LE_CH_FDM explicit / explicit (dt 0.005) DC, 2 spheres", merge(
        common(LECH, dt=0.005), solvers(LECH, ns="explicit_scheme", ch="explicit_scheme"),
        spheres(REST2, mass=1.0), shear(LECH)), 200),
    "lech_ii": ("Shear_NS_LE_CH_FDM implicit / implicit DC, 2 spheres", merge(
        common(LECH), solvers(LECH, ns="implicit_scheme", ch="implicit_scheme"),
        spheres(REST2, mass=1.0), shear(LECH)), 200),
    "el_salt": ("Electrolyte salt, DC field x, 2 charged spheres (dt 0.005)", merge(
        common(EL, dt=0.005), spheres(REST2, mass=1.0),
        {"object_type.spherical_particle.Particle_spec[0].Surface_charge": -5.0,
         f"constitutive_eq.{EL}.kBT": 1.0,      # the ions' temperature (no particle noise here)
         f"constitutive_eq.{EL}.INIT_profile": "Uniform",
         f"constitutive_eq.{EL}.Add_salt.type": "salt",
         f"constitutive_eq.{EL}.Add_salt.salt.Debye_length": 4.0,
         f"constitutive_eq.{EL}.Electric_field.type": "ON",
         f"constitutive_eq.{EL}.Electric_field.ON.type": "DC",
         f"constitutive_eq.{EL}.Electric_field.ON.DC.Ex": 0.01,
         f"constitutive_eq.{EL}.Electric_field.ON.DC.Ey": 0.0,
         f"constitutive_eq.{EL}.Electric_field.ON.DC.Ez": 0.0}), 200),
    "el_sphere": ("Electrolyte salt, DC field x+y, 1 charged sphere off the grid (dt 0.005)", merge(
        common(EL, dt=0.005), spheres([row((15.6, 16.3, 16.1))], mass=1.0),
        {"object_type.spherical_particle.Particle_spec[0].Surface_charge": -10.0,
         f"constitutive_eq.{EL}.kBT": 1.0,
         f"constitutive_eq.{EL}.INIT_profile": "Uniform",
         f"constitutive_eq.{EL}.Add_salt.type": "salt",
         f"constitutive_eq.{EL}.Add_salt.salt.Debye_length": 3.0,
         f"constitutive_eq.{EL}.Electric_field.type": "ON",
         f"constitutive_eq.{EL}.Electric_field.ON.type": "DC",
         f"constitutive_eq.{EL}.Electric_field.ON.DC.Ex": 0.02,
         f"constitutive_eq.{EL}.Electric_field.ON.DC.Ey": 0.01,
         f"constitutive_eq.{EL}.Electric_field.ON.DC.Ez": 0.0}), 200),
}


# ---------------------------------------------------------------- building and running
def make_input(d: Path, edits: dict, steps: int, kref: Path):
    """input.udf (+ define.udf, kapsel_unit.udf) of a scene in d, and input.flat for the
    original; Num_snap from steps / GTS."""
    d.mkdir(parents=True, exist_ok=True)
    edits = dict(edits)
    base = Path(edits.pop("_base", BASE))
    for f in ("define.udf", "kapsel_unit.udf"):
        if (base.parent / f).exists():
            shutil.copy(base.parent / f, d / f)
    u = UDFManager(str(base))
    edits["output.Num_snap"] = max(1, steps // int(edits.get("output.GTS", 10)))
    for k, v in edits.items():
        if isinstance(v, list) and v and isinstance(v[0], list):
            v = np.array(v, dtype=float)
        u.put(v, k)
    u.write(str(d / "input.udf"))
    subprocess.run([sys.executable, str(kref / "flatten_udf.py"), "input.udf", "input.flat"],
                   cwd=d, check=True, env=dict(os.environ, PYTHONPATH=str(ROOT)))


def _peak_rss_kb():
    import resource
    return resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss


def run(prog, d: Path, original: str, cache: Path | None = None):
    """Run one program in d/<prog>; returns rc, wall s, the tail of stderr.  The original's
    run of a document is kept in ``cache`` (keyed by the flat input and the binary) and reused:
    it does not change while kapsel-py does."""
    w = d / prog
    if w.exists():
        shutil.rmtree(w)
    key = None
    if prog == "cpp" and cache is not None:
        import hashlib
        h = hashlib.sha256((d / "input.flat").read_bytes())
        st = os.stat(original)
        h.update(f"{os.path.realpath(original)} {st.st_size} {st.st_mtime_ns}".encode())
        key = cache / h.hexdigest()[:20]
        if (key / "done.json").exists():
            shutil.copytree(key, w)
            meta = json.loads((key / "done.json").read_text())
            return meta["rc"], meta["wall"], meta["tail"]
    w.mkdir()
    for f in ("input.udf", "input.flat", "define.udf", "kapsel_unit.udf"):
        if (d / f).exists():
            shutil.copy(d / f, w / f)
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    if prog == "cpp":
        cmd = [original, "-Iinput.flat", "-Ooutput.flat", "-Ddefine.udf", "-Rrestart.flat"]
    else:
        cmd = [sys.executable, "-c", "import sys; from kapsel.cli import main; "
               "sys.argv[0] = 'kapsel-py'; sys.exit(main())",
               "-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--threads", "1",
               "--seed", "1", "--quiet"]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=w, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    (w / "stderr.txt").write_text(p.stderr)
    (w / "stdout.txt").write_text(p.stdout)
    tail = (p.stderr.strip().splitlines() or [""])[-1][:160]
    if key is not None:
        if key.exists():
            shutil.rmtree(key)
        shutil.copytree(w, key)
        (key / "done.json").write_text(json.dumps({"rc": p.returncode, "wall": wall,
                                                   "tail": tail}))
    return p.returncode, wall, tail


# ---------------------------------------------------------------- reading the records
_ITEM = re.compile(r"^(Particles|RigidParticles)\[(\d+)\]\.(\w+)\.(\w+)$")
_COMP = {"x": 0, "y": 1, "z": 2, "q0": 0, "q1": 1, "q2": 2, "q3": 3}


def records_original(path: Path):
    """{'t': (n,), 'Particles': {name: (n, N, c)}, 'RigidParticles': ...} of the kref flat
    output (``record<TAB>path<TAB>value`` lines)."""
    recs = defaultdict(list)
    with open(path) as fh:
        for line in fh:
            if line.startswith("#"):
                continue
            parts = line.rstrip("\n").split("\t", 2)
            if len(parts) == 3 and parts[0].lstrip("-").isdigit() and int(parts[0]) >= 0:
                recs[int(parts[0])].append((parts[1], parts[2]))
    out = {"t": [], "Particles": defaultdict(list), "RigidParticles": defaultdict(list)}
    for r in sorted(recs):
        d = {"Particles": defaultdict(dict), "RigidParticles": defaultdict(dict)}
        for p, v in recs[r]:
            if p == "t":
                out["t"].append(float(v))
            m = _ITEM.match(p)
            if m and m.group(4) in _COMP:
                d[m.group(1)][m.group(3)][(int(m.group(2)), _COMP[m.group(4)])] = float(v)
        for kind in ("Particles", "RigidParticles"):
            for name, vals in d[kind].items():
                n = max(i for i, _ in vals) + 1
                c = max(j for _, j in vals) + 1
                a = np.zeros((n, c))
                for (i, j), x in vals.items():
                    a[i, j] = x
                out[kind][name].append(a)
    return _arrays(out)


def records_py(path: Path):
    u = UDFManager(str(path))
    out = {"t": [], "Particles": defaultdict(list), "RigidParticles": defaultdict(list)}
    for r in range(u.totalRecord()):
        u.jump(r)
        out["t"].append(float(u.get("t")))
        for kind in ("Particles", "RigidParticles"):
            for name in ("R", "v", "omega"):
                try:
                    a = np.asarray(u.getArray(f"{kind}[].{name}"), dtype=float)
                except Exception:       # noqa: BLE001 (not in this document)
                    continue
                if a.size:
                    out[kind][name].append(a.reshape(len(a), -1))
    return _arrays(out)


def _arrays(out):
    res = {"t": np.array(out["t"])}
    for kind in ("Particles", "RigidParticles"):
        res[kind] = {}
        for k, v in out[kind].items():
            if len(v) and len({a.shape for a in v}) == 1:
                res[kind][k] = np.array(v)
    return res


def h5_field(path: Path, names):
    import h5py
    with h5py.File(path, "r") as f:
        for n in names:
            if n in f:
                return np.asarray(f[n][...], dtype=float)
    return None


def compare(d: Path, box):
    """The parity columns of a scene run in d/cpp and d/py."""
    c = records_original(d / "cpp" / "output.flat")
    p = records_py(d / "py" / "output.udf")
    kind = "RigidParticles" if "R" in c["RigidParticles"] and "R" in p["RigidParticles"] \
        else "Particles"
    cc, pp = c[kind], p[kind]
    res = {"records": [len(c["t"]), len(p["t"])], "kind": kind}
    if "R" not in cc or "R" not in pp:
        res["error"] = "no particle records"
        return res
    n = min(len(cc["R"]), len(pp["R"]))
    if cc["R"].shape[1:] != pp["R"].shape[1:]:
        res["error"] = f"particle tables differ: {cc['R'].shape} {pp['R'].shape}"
        return res
    L = np.asarray(box, dtype=float)

    def mi(a):
        return a - L * np.round(a / L)
    res["t_match"] = bool(np.array_equal(c["t"][:n], p["t"][:n]))
    motion = np.abs(mi(cc["R"][:n] - cc["R"][:1])).max()
    dR = np.abs(mi(pp["R"][:n] - cc["R"][:n]))
    res["motion"] = float(motion)
    res["dR"] = float(dR.max())
    res["dR_rel"] = float(dR.max() / motion) if motion > 1e-9 else None
    # what the records resolve: kapsel-py's R is written in single precision (shortest
    # decimal of the float), up to one float32 ulp of |R| from the exact value
    res["dR_floor"] = float(np.spacing(np.float32(np.abs(cc["R"][:n]).max())))
    vmax = np.abs(cc["v"][:n]).max()
    dv = np.abs(pp["v"][:n] - cc["v"][:n]).max()
    res["vmax"], res["dv"] = float(vmax), float(dv)
    res["dv_rel"] = float(dv / vmax) if vmax > 1e-12 else None
    if "omega" in cc and "omega" in pp:
        wmax = np.abs(cc["omega"][:n]).max()
        dw = np.abs(pp["omega"][:n] - cc["omega"][:n]).max()
        res["wmax"], res["dw"] = float(wmax), float(dw)
        res["dw_rel"] = float(dw / wmax) if wmax > 1e-12 else None
    # first record where the relative difference passes 1e-3 (where they part ways)
    per = dR.max(axis=(1, 2)) / motion if motion > 0 else np.zeros(n)
    bad = np.flatnonzero(per > 1e-3)
    res["parts_at_step"] = float(c["t"][bad[0]]) if len(bad) else None
    # fields of the FDM types at the last snapshot both wrote
    snaps = sorted((int(m.group(1)) for f in (d / "cpp").glob("velocity_*.h5")
                    if (m := re.match(r"velocity_(\d+)\.h5$", f.name))), reverse=True)
    for s in snaps:
        fp = d / "py" / f"velocity_{s}.h5"
        if not fp.exists():
            continue
        uc = [h5_field(d / "cpp" / f"velocity_{s}.h5", [k]) for k in ("UX", "UY", "UZ")]
        up = [h5_field(fp, [k]) for k in ("UX", "UY", "UZ")]
        if all(a is not None for a in uc + up) and uc[0].shape == up[0].shape:
            num = sum(np.sum((a - b) ** 2) for a, b in zip(up, uc))
            den = sum(np.sum(b ** 2) for b in uc)
            res["u_L2"] = float(np.sqrt(num / den)) if den > 0 else None
            res["field_snapshot"] = s
        oc, op = d / "cpp" / f"orderparam_{s}.h5", d / "py" / f"orderparam_{s}.h5"
        if oc.exists() and op.exists():
            a = h5_field(oc, ["PSI_ALL", "PSI"])
            b = h5_field(op, ["PSI_ALL", "PSI"])
            if a is not None and b is not None and a.shape == b.shape:
                res["psi_L2"] = float(np.linalg.norm(b - a) / max(np.linalg.norm(a), 1e-300))
        break
    return res


def fmt(x, spec=".2e"):
    return "-" if x is None else format(x, spec)


def rel(c, key, ref, absolute):
    """The relative difference, or 'abs <difference>' when the original's reference value
    is 0 (a symmetric scene: a particle at rest or not rotating)."""
    if c.get(key) is not None:
        return fmt(c[key])
    if c.get(absolute) is not None:
        return "abs " + fmt(c[absolute], ".1e")
    return "-"


def floor(c):
    """' (f32)' when dR is within the single-precision records' resolution of R."""
    if c.get("dR") is not None and c.get("dR_floor") is not None and c["dR"] <= c["dR_floor"]:
        return " (f32)"
    return ""


def table(results):
    head = ("| scene | what | steps | motion | dR/motion | dv/max v | dw/max w | u L2 | psi L2 "
            "| rc orig/py |")
    lines = [head, "|" + "---|" * 10]
    for name, r in results.items():
        c = r.get("cmp", {})
        lines.append(
            f"| {name} | {r['label']} | {r['steps']} | {fmt(c.get('motion'), '.3g')} | "
            f"{rel(c, 'dR_rel', 'motion', 'dR')}{floor(c)} | {rel(c, 'dv_rel', 'vmax', 'dv')} | "
            f"{rel(c, 'dw_rel', 'wmax', 'dw')} | "
            f"{fmt(c.get('u_L2'))} | {fmt(c.get('psi_L2'))} | {r['rc'][0]}/{r['rc'][1]}"
            + (f" {c['error']}" if "error" in c else "") + " |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--original", default=os.environ.get("KREF_CPP"),
                    help="the original's binary (kref build; or $KREF_CPP)")
    ap.add_argument("--kref", default=os.environ.get("KREF_TOOLS",
                                                     str(ROOT.parent / "shared" / "kref")),
                    help="the kref tools' directory (flatten_udf.py); or $KREF_TOOLS")
    ap.add_argument("--scene", nargs="*", help="scenes to run (default all; see --list)")
    ap.add_argument("--steps", type=int, help="steps of every scene (default its own)")
    ap.add_argument("--keep", help="keep the runs under this directory")
    ap.add_argument("--json", help="write the results as JSON here")
    ap.add_argument("--list", action="store_true", help="list the scenes and exit")
    ap.add_argument("--cache", default=os.environ.get("KAPSEL_PARITY_CACHE"),
                    help="keep and reuse the original's runs here (or $KAPSEL_PARITY_CACHE)")
    a = ap.parse_args(argv)
    if a.list:
        for k, v in SCENES.items():
            print(f"{k:16s} {v[0]}")
        return 0
    kref = Path(a.kref).resolve()        # the scenes run in their own directories
    if not a.original or not Path(a.original).is_file() or not (kref / "flatten_udf.py").exists():
        print("bench/parity.py needs the original program and the kref tools:\n"
              "  build it: KREF=<scratch dir> KAPSEL3_GIT=<git dir of kapsel-dns/kapsel3> "
              "../shared/kref/build.sh\n"
              "  then: bench/parity.py --original <scratch dir>/src/kapsel "
              "[--kref ../shared/kref]", file=sys.stderr)
        return 2
    names = a.scene or list(SCENES)
    unknown = [n for n in names if n not in SCENES]
    if unknown:
        print(f"unknown scene(s): {' '.join(unknown)} (see --list)", file=sys.stderr)
        return 2
    top = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="kapsel-parity-"))
    results = {}
    load0 = os.getloadavg()[0]
    for name in names:
        label, edits, steps = SCENES[name]
        steps = a.steps or steps
        d = top / name
        make_input(d, edits, steps, kref)
        n = 2 ** int(edits.get("mesh.NPX", 5))
        rc_c, w_c, tail_c = run("cpp", d, str(Path(a.original).resolve()), Path(a.cache) if a.cache else None)
        rc_p, w_p, tail_p = run("py", d, a.original)
        r = {"label": label, "steps": steps, "rc": [rc_c, rc_p], "wall": [w_c, w_p],
             "stderr_tail": [tail_c, tail_p]}
        try:
            if (d / "cpp" / "output.flat").exists() and (d / "py" / "output.udf").exists():
                r["cmp"] = compare(d, (n, n, n))
        except Exception as e:  # noqa: BLE001 (report and go on)
            r["cmp"] = {"error": f"{type(e).__name__}: {e}"}
        results[name] = r
        c = r.get("cmp", {})
        print(f"{name:16s} rc {rc_c}/{rc_p}  "
              f"dR/motion {rel(c, 'dR_rel', 'motion', 'dR')}{floor(c)}  "
              f"dv/v {rel(c, 'dv_rel', 'vmax', 'dv')}  dw/w {rel(c, 'dw_rel', 'wmax', 'dw')}  "
              f"u {fmt(c.get('u_L2'))}  psi {fmt(c.get('psi_L2'))}  "
              f"({w_c:.1f} s / {w_p:.1f} s)" + (f"  {c['error']}" if "error" in c else "")
              + (f"  [orig: {tail_c}]" if rc_c else "") + (f"  [py: {tail_p}]" if rc_p else ""),
              flush=True)
    stamp = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    print(f"\n{stamp}, {os.uname().nodename}, load {load0:.1f} -> {os.getloadavg()[0]:.1f}, "
          f"kapsel-py {subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=ROOT, capture_output=True, text=True).stdout.strip()}\n")
    print(table(results))
    if a.json:
        Path(a.json).write_text(json.dumps({"when": stamp, "results": results}, indent=1))
    if not a.keep:
        shutil.rmtree(top, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
