"""restart.udf: the input's data with ``resume.Calculation`` set and ``Saved_Data`` filled,
in the define.udf ``resume`` schema (manual table 7).  Written atomically at every snapshot
and at the end, so a failed or interrupted run leaves the last good state behind.

    CONTINUE_FDM                    jikan, Particles[] (sParticle), U, U_OLD
    CONTINUE_FDM_PHASE_SEPARATION   ... plus PSI, PSI_OLD, STRESS_OLD
"""
from __future__ import annotations

import numpy as np

from udf import UDFManager

from .records import particle_table


def vector_field(u: np.ndarray) -> np.ndarray:
    """(3, NX, NY, NZ) -> (NX, NY, NZ, 3), the layout of U[][][]: {u0, u1, u2}."""
    return np.ascontiguousarray(np.moveaxis(u, 0, -1))


def write_restart(path: str, define_path: str, input_doc: UDFManager, kind: str, step: int,
                  time: float, particles, fields: dict) -> None:
    doc = UDFManager(schema_from=define_path)
    for name, value in input_doc.common.items():
        if name in doc.schema.global_items:
            doc.common[name] = value
    doc.put(kind, "resume.Calculation")
    base = f"resume.{kind}.Saved_Data"
    doc.put([int(step), float(time)], f"{base}.jikan")
    if particles is not None and particles.n:
        m, _ = doc.schema.item("resume")
        sd = m.type.members[m.type.index(kind)].type.members[0].type
        ptype = sd.members[sd.index("Particles")].type
        doc.put(particle_table(particles, ptype), f"{base}.Particles[]")
    for name, arr in fields.items():
        doc.put(arr, f"{base}.{name}[]")
    doc.write(path)
