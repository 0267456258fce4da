"""``kapsel-py analyze erotate``: rotational energy of every rigid body and the total, per
record of a kapsel output.udf (spec 002 eqs 1-7).

Bodies follow ``object_type.rigid.Rigid_spec[]``: Chain_number bodies of Beads_number beads
per species, in order; bead mass m = MASS_RATIO RHO 4/3 pi A^3; the body angular velocity is
``RigidParticles[g].omega`` when the record has it, else the beads' mean omega.
"""
from __future__ import annotations

import sys

import numpy as np

from .rotational_energy import rotational_energies


def bodies(u):
    """(body id per bead, bead masses) from the common data."""
    if u.get("object_type.type") != "rigid":
        raise ValueError("object_type.type is not 'rigid': the file has no rigid bodies")
    eq = u.get("constitutive_eq.type")
    rho = u.get(f"constitutive_eq.{eq}.RHO")
    A = u.get("A")
    ids, masses, g = [], [], 0
    for spec in u.get("object_type.rigid.Rigid_spec[]"):
        beads, number, ratio = spec[0], spec[1], spec[2]
        for _ in range(number):
            ids += [g] * beads
            masses += [ratio * rho * 4.0 / 3.0 * np.pi * A ** 3] * beads
            g += 1
    return np.array(ids, dtype=np.int64), np.array(masses)


def run(a) -> int:
    import udf
    try:
        u = udf.UDFManager(a.file)
        body, masses = bodies(u)
        eq = u.get("constitutive_eq.type")
        box = np.array([2 ** u.get(f"mesh.{x}") for x in ("NPX", "NPY", "NPZ")], float) * \
            u.get(f"constitutive_eq.{eq}.DX")
        print("record        time   E_rot(total)   E_rot per body")
        for r in range(u.totalRecord()):
            u.jump(r)
            R = u.getArray("Particles[].R_raw")
            if len(R) != len(body):
                raise ValueError(f"record {r} has {len(R)} beads, Rigid_spec gives {len(body)}")
            ng = int(body.max()) + 1 if len(body) else 0
            if u.size("RigidParticles[]") >= ng:
                omega = u.getArray("RigidParticles[].omega")[:ng]
            else:
                om = u.getArray("Particles[].omega")
                omega = np.array([om[body == k].mean(axis=0) for k in range(ng)])
            e = rotational_energies(omega, masses, R, body, box)
            print(f"{r:6d} {u.get('t'):11.5g} {e.sum():14.6g}   "
                  + " ".join(f"{x:.6g}" for x in e))
    except Exception as e:  # one line for the user, never a traceback
        print(f"kapsel-py analyze erotate: error: {e}", file=sys.stderr)
        return 2
    return 0
