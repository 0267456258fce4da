"""restart.udf: write the state of a run, and read it back to continue the run.

The restart file is the input's data with ``resume.Calculation`` set and ``Saved_Data``
filled, in the define.udf ``resume`` schema (manual table 7), so it is itself a complete
input: ``kapsel-py -Irestart.udf ...`` continues the run.

    CONTINUE (or CONTINUE_ORIGINAL) jikan, Particles[] (sParticle), Zeta, uk_dc, oblique
    CONTINUE_FDM                    jikan, Particles[] (sParticle), U, U_OLD
    CONTINUE_FDM_PHASE_SEPARATION   ... plus PSI, PSI_OLD, STRESS_OLD

Floats are written in full (shortest round-trip) precision.  What the schema has no place
for -- the unwrapped positions R_raw, the state of the thermal-noise generator, the
spectral velocity u_hat itself, solver history flags -- goes to a companion file
``<restart>.state.npz`` (written first; both atomically).  It carries a fingerprint of the
schema data it belongs to; with it a continued run is bit-identical to an uninterrupted one.
Without it (a restart.udf written by another program, or edited by hand), the run continues
from the schema data alone: R_raw restarts at R, the noise stream at the run's seed.

Zeta (CONTINUE) holds the vorticity components omega_x, omega_z of the velocity in Fourier
space (forward transform normalised by 1/N, real and imaginary parts interleaved along z,
NZ + 2 entries) and uk_dc its k = 0 part (the mean velocity).  That packing is our reading
of the original's; as it cannot represent the ky = 0 plane completely, kapsel-py continues
a CONTINUE restart only together with its state file.
"""
from __future__ import annotations

import hashlib
import json
import os
import zipfile
from dataclasses import dataclass, field

import numpy as np

from udf import UDFManager

from .records import OUT_FIELDS, particle_table

STATE_SUFFIX = ".state.npz"


def schema_kind(doc: UDFManager, kind: str) -> str:
    """The name the schema uses for ``kind``: the spectral restart is ``CONTINUE`` in some
    define.udf versions and ``CONTINUE_ORIGINAL`` (the manual's name) in others."""
    m, _ = doc.schema.item("resume")
    names = [mem.name for mem in m.type.members]
    if kind in ("CONTINUE", "CONTINUE_ORIGINAL"):
        for k in ("CONTINUE", "CONTINUE_ORIGINAL"):
            if k in names:
                return k
    return kind


def same_kind(a: str, b: str) -> bool:
    alias = {"CONTINUE_ORIGINAL": "CONTINUE"}
    return alias.get(a, a) == alias.get(b, b)


def state_path(restart_path: str) -> str:
    """The companion file holding what the schema cannot (see module docstring)."""
    return os.fspath(restart_path) + STATE_SUFFIX


def vector_field(u: np.ndarray) -> np.ndarray:
    """(3, NX, NY, NZ) -> (NX, NY, NZ, 3), the layout of U[][][]: {u0, u1, u2}."""
    return np.ascontiguousarray(np.moveaxis(u, 0, -1))


def component_field(v: np.ndarray) -> np.ndarray:
    """(NX, NY, NZ, 3) -> (3, NX, NY, NZ), the inverse of :func:`vector_field`."""
    return np.ascontiguousarray(np.moveaxis(np.asarray(v, dtype=float), -1, 0))


@dataclass
class Saved:
    """``resume.<kind>.Saved_Data`` as read: clock, particle table, fields by name."""
    kind: str
    step: int
    time: float
    particles: np.ndarray | None             # (N, leaves of sParticle) or None
    fields: dict = field(default_factory=dict)
    exact: dict | None = None                 # the state file's arrays, if it matches
    particle_struct: object = None            # the sParticle class of the schema
    state_damaged: str | None = None          # why the state file could not be read
    checkpoint_of: int | None = None          # the step of restart.udf, when the state
    #                                           file held a later checkpoint (taken instead)

    def fingerprint(self) -> str:
        return fingerprint(self.step, self.time, self.particles, self.fields)


def fingerprint(step, time, particles, fields) -> str:
    """SHA-256 of the schema data of a restart (as float64 bytes), pairing it with its
    state file."""
    h = hashlib.sha256()
    h.update(repr((int(step), float(time))).encode())
    if particles is not None:
        h.update(np.ascontiguousarray(particles, dtype=np.float64).tobytes())
    for name in sorted(fields):
        h.update(name.encode())
        h.update(np.ascontiguousarray(fields[name], dtype=np.float64).tobytes())
    return h.hexdigest()


def _saved_data_type(doc: UDFManager, kind: str):
    """The Struct of ``resume.<kind>.Saved_Data``."""
    m, _ = doc.schema.item("resume")
    return m.type.members[m.type.index(kind)].type.members[0].type


def _sparticle_type(doc: UDFManager, kind: str):
    sd = _saved_data_type(doc, kind)
    return sd.members[sd.index("Particles")].type


def _savez_tmp(path: str, arrays: dict) -> str:
    """Write the arrays to a temporary file next to ``path``; returns its name (removed
    again if the write fails)."""
    tmp = f"{path}.tmp{os.getpid()}"
    try:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
    except BaseException:
        _remove(tmp)
        raise
    return tmp


def _remove(path):
    try:
        os.unlink(path)
    except OSError:
        pass


def write_restart(path: str, define_path: str, input_doc: UDFManager, kind: str, step: int,
                  time: float, particles, fields: dict, exact: dict | None = None,
                  table: np.ndarray | None = None) -> str:
    """Write ``path`` (restart.udf) and its state file.  ``fields``: Saved_Data items by
    name (``oblique`` etc. as plain values); ``exact``: arrays (or JSON-able values) the
    schema has no place for; ``table``: the sParticle table instead of ``particles``.
    Returns the fingerprint of the data written (``write_checkpoint``'s ``base``)."""
    doc = UDFManager(schema_from=define_path)
    for name, value in input_doc.common.items():
        if name in doc.schema.global_items:
            doc.common[name] = value
    kind = schema_kind(doc, kind)
    doc.put(kind, "resume.Calculation")
    base = f"resume.{kind}.Saved_Data"
    doc.put([int(step), float(time)], f"{base}.jikan")
    if table is None and particles is not None and particles.n:
        table = particle_table(particles, _sparticle_type(doc, kind))
    if table is not None:
        doc.put(table, f"{base}.Particles[]")
    arrays = {}
    for name, value in fields.items():
        if isinstance(value, np.ndarray):
            doc.put(value, f"{base}.{name}[]")
            arrays[name] = value
        else:
            doc.put(value, f"{base}.{name}")
    fp = fingerprint(step, time, table, arrays)
    state = {"fingerprint": np.array(fp)}
    _put_exact(state, exact)
    # both files are written in full under temporary names before either replaces the
    # previous pair: a failure (a full disk) leaves the last good restart and state file
    spath = state_path(path)
    try:
        stmp = _savez_tmp(spath, state)
    except OSError as e:
        raise OSError(e.errno, e.strerror, spath) from None
    utmp = f"{path}.tmp{os.getpid()}"
    try:
        doc.write(utmp)
    except OSError as e:
        _remove(stmp)
        _remove(utmp)
        raise OSError(e.errno, e.strerror, path) from None
    except BaseException:
        _remove(stmp)
        _remove(utmp)
        raise
    os.replace(stmp, spath)
    os.replace(utmp, path)
    return fp


def _put_exact(state: dict, exact) -> None:
    for name, value in (exact or {}).items():
        if isinstance(value, np.ndarray):
            state[name] = value
        else:
            state[name] = np.array(json.dumps(value))


def _decode(v):
    return json.loads(str(v)) if v.dtype.kind == "U" else v


# -------------------------------------------------------------------- checkpoints
# Rewriting restart.udf's text at every snapshot costs several time steps at 64^3 (issue 14).
# Between full writes, a run writes only the state file, which then also holds the schema
# data (binary) and the fingerprint of the restart.udf it continues (``checkpoint_base``):
# read_restart continues from that newer state, so a run killed at any moment continues
# from its last snapshot; the full restart.udf is written at the run's first snapshot, at
# its end, when it is interrupted, and when it fails (from the last checkpoint).
_CK = "checkpoint:"


def write_checkpoint(path: str, define_doc: UDFManager, kind: str, step: int, time: float,
                     particles, fields: dict, exact: dict | None, base: str,
                     complete: bool = True) -> None:
    """Replace ``path``'s state file by a checkpoint continuing the restart.udf whose
    fingerprint is ``base`` (``define_doc``: a UDFManager(schema_from=define.udf)).
    ``complete``: ``fields`` are all the Saved_Data fields (else only what the model needs
    to continue, e.g. the spectral velocity in ``exact`` without its Zeta packing)."""
    kind = schema_kind(define_doc, kind)
    state = {"fingerprint": np.array(""), _CK + "base": np.array(base),
             _CK + "kind": np.array(kind), _CK + "step": np.array(int(step)),
             _CK + "time": np.array(float(time)), _CK + "complete": np.array(bool(complete))}
    if particles is not None and particles.n:
        state[_CK + "particles"] = particle_table(particles, _sparticle_type(define_doc, kind))
    for name, value in fields.items():
        if isinstance(value, np.ndarray):
            state[_CK + "field:" + name] = value
        else:
            state[_CK + "value:" + name] = np.array(json.dumps(value))
    _put_exact(state, exact)
    spath = state_path(path)
    try:
        tmp = _savez_tmp(spath, state)
    except OSError as e:
        raise OSError(e.errno, e.strerror, spath) from None
    os.replace(tmp, spath)


def _split_checkpoint(state: dict):
    """(kind, step, time, table, fields, exact) of a checkpoint state."""
    ck = {k[len(_CK):]: state[k] for k in state if k.startswith(_CK)}
    exact = {k: _decode(v) for k, v in state.items()
             if not k.startswith(_CK) and k != "fingerprint"}
    fields = {k[6:]: v for k, v in ck.items() if k.startswith("field:")}
    fields.update({k[6:]: json.loads(str(v)) for k, v in ck.items() if k.startswith("value:")})
    ck.pop("complete", None)
    return (str(ck["kind"]), int(ck["step"]), float(ck["time"]), ck.get("particles"), fields,
            exact)


def complete_restart(path: str, define_path: str, input_doc: UDFManager) -> int | None:
    """Write the full restart.udf of the checkpoint in its state file (a run that failed
    after its last checkpoint); returns its step, or None if the state is no checkpoint."""
    try:
        state = _read_state(state_path(path))
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile):
        return None
    if _CK + "base" not in state or not bool(state.get(_CK + "complete", False)):
        return None
    kind, step, time, table, fields, exact = _split_checkpoint(state)
    write_restart(path, define_path, input_doc, kind, step, time, None, fields, exact,
                  table=table)
    return step


def read_restart(doc: UDFManager, input_path: str, kind: str) -> Saved:
    """``resume.<kind>.Saved_Data`` of an input document (a restart.udf), with the arrays
    of its state file when that file exists and belongs to exactly this data."""
    base = f"resume.{kind}.Saved_Data"
    step, time = doc.get(f"{base}.jikan")
    table = None
    if doc.size(f"{base}.Particles[]"):
        table = np.asarray(doc.getArray(f"{base}.Particles[]"), dtype=np.float64)
    fields = {}
    for member in _saved_data_type(doc, kind).members:
        name = member.name
        if name in ("jikan", "Particles") or member.ndim == 0:
            continue
        if doc.size(f"{base}.{name}[]"):
            arr = np.asarray(doc.getArray(f"{base}.{name}[]"), dtype=np.float64)
            if arr.ndim == member.ndim + 1 and arr.shape[-1] == 1:
                arr = arr[..., 0]                   # a one-member class, e.g. {psi: float}
            fields[name] = arr
    saved = Saved(kind, int(step), float(time), table, fields,
                  particle_struct=_sparticle_type(doc, kind))
    path = state_path(input_path)
    if os.path.exists(path):
        try:
            state = _read_state(path)
        except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as e:
            saved.state_damaged = (e.strerror if isinstance(e, OSError) and e.strerror
                                   else str(e) or type(e).__name__)
            return saved
        mine = saved.fingerprint()
        if str(state.pop("fingerprint", "")) == mine:
            saved.exact = {k: _decode(v) for k, v in state.items()}
        elif str(state.get(_CK + "base", "")) == mine:
            ck_kind, step, time, table, fields, exact = _split_checkpoint(state)
            if same_kind(ck_kind, kind) and step >= saved.step:
                saved = Saved(kind, step, time, table, fields, exact,
                              particle_struct=saved.particle_struct,
                              checkpoint_of=saved.step)
    return saved


def _read_state(path):
    """The arrays of a state file; raises for a file that is not one (damaged, empty,
    truncated, a directory)."""
    with np.load(path, allow_pickle=False) as z:
        if not hasattr(z, "files"):
            raise ValueError("not an .npz archive")
        return {k: z[k] for k in z.files}


def zeta_from_velocity(u: np.ndarray, dx: float):
    """(Zeta (NX, NY, NZ + 2, 2), uk_dc (3,)) of a real velocity (3, NX, NY, NZ): the
    vorticity components omega_x, omega_z of the 1/N-normalised r2c transform, (re, im)
    interleaved along z; uk_dc the k = 0 part (see the module docstring)."""
    shape = u.shape[1:]
    uk = np.fft.rfftn(u, axes=(1, 2, 3)) / float(np.prod(shape))
    k = [2 * np.pi * np.fft.fftfreq(n, dx) for n in shape[:2]]
    k.append(2 * np.pi * np.fft.rfftfreq(shape[2], dx))
    kx, ky, kz = np.meshgrid(*k, indexing="ij")
    wx = 1j * (ky * uk[2] - kz * uk[1])
    wz = 1j * (kx * uk[1] - ky * uk[0])
    zeta = np.empty(shape[:2] + (2 * uk.shape[-1], 2))
    for c, w in enumerate((wx, wz)):
        zeta[:, :, 0::2, c] = w.real
        zeta[:, :, 1::2, c] = w.imag
    return zeta, uk[:, 0, 0, 0].real.copy()


def particles_from_table(state, table: np.ndarray, struct) -> None:
    """Fill a ParticleState from a (N, leaves) sParticle table (inverse of particle_table).
    The table's rows must match the state's particle count."""
    from udf.schema import leaf_slice
    if table.shape[0] != state.n:
        raise ValueError(f"the restart holds {table.shape[0]} particles, the input "
                         f"describes {state.n}")
    done = set()
    for m in struct.members:
        attr = OUT_FIELDS.get(m.name)
        if attr is None or attr in done or m.name in ("f_hydro1", "torque_hydro1"):
            continue
        off, cnt, _ = leaf_slice(struct, [m.name])
        getattr(state, attr)[:] = table[:, off:off + cnt]
        done.add(attr)
