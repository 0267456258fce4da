"""restart.udf: write the state of a run, and read it back to continue the run.

The restart file is the input's data with ``resume.Calculation`` set and ``Saved_Data``
filled, in the define.udf ``resume`` schema (manual table 7), so it is itself a complete
input: ``kapsel-py -Irestart.udf ...`` continues the run.

    CONTINUE (or CONTINUE_ORIGINAL) jikan, Particles[] (sParticle), Zeta, uk_dc, oblique
    CONTINUE_FDM                    jikan, Particles[] (sParticle), U, U_OLD
    CONTINUE_FDM_PHASE_SEPARATION   ... plus PSI, PSI_OLD, STRESS_OLD

With rigid bodies Particles[] holds one row per body (its centre, velocities, quaternion,
summed forces) and GR_body[], GR_masses[], GR_moments_body[] their geometry, as the
original writes them (``saved_rows``; kapsel.particles.rigid ``restart_rows``).

Floats are written in full (shortest round-trip) precision.  What the schema has no place
for -- the unwrapped positions R_raw, the state of the thermal-noise generator, solver
history, stress accumulators -- goes to a companion file ``<restart>.state.npz`` (written
first; both atomically).  It carries a fingerprint of the schema data it belongs to; with
it a continued run is bit-identical to an uninterrupted one.  Without it (a restart.udf
written by the original program, or edited by hand), the run continues from the schema
data alone: R_raw from its Particles[] (else R), quaternions normalised (as the original
restores them), the noise stream at the run's seed.

Step and time (FORMAT-OUTPUT.md §6.3): the original fills its restart after the step of
its last loop iteration, so the saved state has had ``jikan.ts + 1`` steps and
``jikan.time`` is the time after them.  Both directions use that convention here: a state
after n steps is written as ts = n - 1, time = t(n), and a restart's ts is read as
ts + 1 steps done.

Spectral restarts (CONTINUE / CONTINUE_ORIGINAL) hold the velocity as the original packs
it (FORMAT.md "The spectral restart"): ``Zeta[i][j][k]`` {zeta0, zeta1}, two vorticity
components omega = i k x u^ of the unnormalised r2c transform (real and imaginary parts at
k = 2m, 2m + 1 for z-mode m; the N/2 modes counted positive), which two depending on the
mode (:func:`pack_zeta`), and ``uk_dc`` the k = 0 coefficient.  The velocity comes back as
u^ = i k x omega / |k|^2 (:func:`unpack_zeta`), exactly for a solenoidal field.
Lees-Edwards: the covariant components in the oblique frame, the middle case chosen by
n_z != 0 (``sheared=True``), uk_dc covariant too; back to velocity the field is
metric-projected (kapsel.models.shear).  FORMAT.md does not say which of omega_x, omega_z
is zeta0 in the last case (n_x = n_z = 0); we take omega_x.  The Lees-Edwards packing is
our reading of FORMAT.md, not checked against a file the original wrote.
"""
from __future__ import annotations

import hashlib
import json
import os
import zipfile
from dataclasses import dataclass, field

import numpy as np

from udf import UDFManager
from udf.files import create_temporary, open_regular, put_in_place

from .records import OUT_FIELDS, particle_table as _record_table

STATE_SUFFIX = ".state.npz"
FIELD_PREFIX = "Saved_Data."   # Saved_Data items the user's define.udf has no place for


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
    step: int                                 # steps done: jikan.ts + 1
    time: float
    particles: np.ndarray | None             # (N, leaves of sParticle) or None
    fields: dict = field(default_factory=dict)
    exact: dict | None = None                 # the state file's arrays, if it matches
    particle_struct: object = None            # the sParticle class of the schema
    state_damaged: str | None = None          # why the state file could not be read
    checkpoint_of: int | None = None          # the step of restart.udf, when the state
    #                                           file held a later checkpoint (taken instead)
    text_fingerprint: str | None = None       # of the restart.udf text itself

    def fingerprint(self) -> str:
        return fingerprint(self.step - 1, self.time, self.particles, self.fields)


def fingerprint(step, time, particles, fields) -> str:
    """SHA-256 of the schema data of a restart (as float64 bytes), pairing it with its
    state file."""
    h = hashlib.sha256()
    h.update(repr((int(step), float(time))).encode())
    if particles is not None:
        h.update(np.ascontiguousarray(particles, dtype=np.float64).data)
    for name in sorted(fields):
        if not isinstance(fields[name], np.ndarray):
            continue                    # uk_dc, oblique: small structs, not fingerprinted
        h.update(name.encode())
        h.update(np.ascontiguousarray(fields[name], dtype=np.float64).data)   # no copy
    return h.hexdigest()


def _saved_data_type(doc: UDFManager, kind: str):
    """The Struct of ``resume.<kind>.Saved_Data``."""
    m, _ = doc.schema.item("resume")
    return m.type.members[m.type.index(kind)].type.members[0].type


def _sparticle_type(doc: UDFManager, kind: str):
    sd = _saved_data_type(doc, kind)
    return sd.members[sd.index("Particles")].type


def _savez_tmp(path: str, arrays: dict) -> str:
    """Write the arrays as an .npz archive to a temporary file next to ``path``, synced;
    returns its name (removed again if the write fails).  Unlike numpy.savez, the archive
    entries carry a fixed date (1980-01-01), so the same state gives the same bytes."""
    fd, tmp = create_temporary(path)
    try:
        with os.fdopen(fd, "wb") as fh:
            with zipfile.ZipFile(fh, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
                for name, value in arrays.items():
                    info = zipfile.ZipInfo(name + ".npy", date_time=(1980, 1, 1, 0, 0, 0))
                    with zf.open(info, "w", force_zip64=True) as entry:
                        np.lib.format.write_array(entry, np.asanyarray(value),
                                                  allow_pickle=False)
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


def write_restart(path: str, define, input_doc: UDFManager, kind: str, step: int,
                  time: float, particles, fields: dict, exact: dict | None = None,
                  table: np.ndarray | None = None, previous: str | None = None) -> str:
    """Write ``path`` (restart.udf) and its state file for the state after ``step`` steps
    (jikan.ts = step - 1, §6.3).  ``fields``: Saved_Data items by name (``oblique`` etc. as
    plain values); ``exact``: arrays (or JSON-able values) the schema has no place for;
    ``table``: the sParticle table instead of ``particles``; ``define``: define.udf's path,
    or a UDFManager(schema_from=define.udf) read once.  Returns the fingerprint of the
    data written (``write_checkpoint``'s ``base``).

    The pair is replaced in two renames, the state file first.  ``previous``: the
    fingerprint of the restart.udf now at ``path`` (written by this run, or the one it
    continues); the new state file is then also a complete checkpoint of that file, so a
    kill between the renames continues from this state, not from the older text.  Without
    it (the file at ``path`` belongs to no run of this time line) the old text is removed
    before the renames."""
    doc = define.blank() if isinstance(define, UDFManager) else UDFManager(schema_from=define)
    for name, value in input_doc.common.items():
        if name in doc.schema.global_items:
            doc.common[name] = _lists_copied(value)
    kind = schema_kind(doc, kind)
    doc.put(kind, "resume.Calculation")
    base = f"resume.{kind}.Saved_Data"
    doc.put([int(step) - 1, float(time)], f"{base}.jikan")   # ts = steps done - 1 (§6.3)
    if table is None and particles is not None and particles.n:
        table = restart_table(saved_rows(particles), _sparticle_type(doc, kind))
    if table is not None:
        doc.put(table, f"{base}.Particles[]")
    arrays, unplaced = {}, {}
    saved_type = _saved_data_type(doc, kind)
    for name, value in fields.items():
        if saved_type.index(name) is None:
            unplaced[name] = value      # an older define.udf (v3.x has no GR_masses[])
            continue
        if isinstance(value, np.ndarray):      # not copied: the document is written and
            doc.put(value, f"{base}.{name}[]", copy=False)      # dropped here (issue 25)
            arrays[name] = value
        else:
            doc.put(value, f"{base}.{name}")
    fp = fingerprint(int(step) - 1, time, table, arrays)
    state = {"fingerprint": np.array(fp)}
    for name, value in unplaced.items():
        state[FIELD_PREFIX + name] = np.asarray(value)
    _put_exact(state, exact)
    if previous is not None:
        _put_checkpoint(state, kind, step, time, table, fields, previous, True)
    # both files are written in full (and synced) under temporary names before either
    # replaces the previous pair: a failure (a full disk) leaves the last good pair
    spath = state_path(path)
    try:
        stmp = _savez_tmp(spath, state)
    except OSError as e:
        raise OSError(e.errno, e.strerror, spath) from None
    try:
        utmp = doc.write(path, place=False)
    except OSError as e:
        _remove(stmp)
        raise OSError(e.errno, e.strerror, path) from None
    except BaseException:
        _remove(stmp)
        raise
    if previous is None and os.path.lexists(path):
        _remove(path)
    put_in_place(stmp, spath)
    put_in_place(utmp, path)
    return fp


def _lists_copied(value):
    """``value`` with its nested lists copied (the leaves shared): the puts of a restart
    replace leaves of the copy, so the input document is left as it was read (it used to
    take in, and hold for the rest of the run, every restart's Saved_Data: 2 float64 per
    grid point of spectral Zeta; issue 25)."""
    if isinstance(value, list):
        return [_lists_copied(v) for v in value]
    return value


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
    state = {"fingerprint": np.array("")}
    table = None
    if particles is not None and particles.n:
        table = restart_table(saved_rows(particles), _sparticle_type(define_doc, kind))
    _put_checkpoint(state, kind, step, time, table, fields, base, complete)
    _put_exact(state, exact)
    spath = state_path(path)
    try:
        tmp = _savez_tmp(spath, state)
    except OSError as e:
        raise OSError(e.errno, e.strerror, spath) from None
    put_in_place(tmp, spath)


def _put_checkpoint(state, kind, step, time, table, fields, base, complete) -> None:
    """The checkpoint entries of a state file: the schema data in binary and the
    fingerprint ``base`` of the restart.udf it continues."""
    state.update({_CK + "base": np.array(base), _CK + "kind": np.array(kind),
                  _CK + "step": np.array(int(step)), _CK + "time": np.array(float(time)),
                  _CK + "complete": np.array(bool(complete))})
    if table is not None:
        state[_CK + "particles"] = np.asarray(table)
    for name, value in fields.items():
        if isinstance(value, np.ndarray):
            state[_CK + "field:" + name] = value
        else:
            state[_CK + "value:" + name] = np.array(json.dumps(value))


def _split_checkpoint(state: dict):
    """(kind, step, time, table, fields, exact) of a checkpoint state."""
    ck = {k[len(_CK):]: state[k] for k in state if k.startswith(_CK)}
    exact = {k: _decode(v) for k, v in state.items()
             if not k.startswith(_CK) and not k.startswith(FIELD_PREFIX)
             and k != "fingerprint"}
    fields = {k[6:]: (v if k.startswith("field:") else json.loads(str(v)))
              for k, v in ck.items() if k.startswith(("field:", "value:"))}   # in order
    ck.pop("complete", None)
    return (str(ck["kind"]), int(ck["step"]), float(ck["time"]), ck.get("particles"), fields,
            exact)


def complete_restart(path: str, define, input_doc: UDFManager) -> int | None:
    """Write the full restart.udf of the checkpoint in its state file (a run that failed
    after its last checkpoint); returns its step, or None if the state is no checkpoint."""
    try:
        state = _read_state(state_path(path))
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile):
        return None
    if _CK + "base" not in state or not bool(state.get(_CK + "complete", False)):
        return None
    kind, step, time, table, fields, exact = _split_checkpoint(state)
    write_restart(path, define, input_doc, kind, step, time, None, fields, exact,
                  table=table, previous=str(state[_CK + "base"]))
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
        if name in ("jikan", "Particles"):
            continue
        if member.ndim == 0:            # a struct such as uk_dc or oblique: a list of values
            try:
                value = doc.get(f"{base}.{name}")
            except (KeyError, IndexError, ValueError, RuntimeError):
                value = None
            if value is not None:
                fields[name] = value if isinstance(value, list) else [value]
            continue
        if doc.size(f"{base}.{name}[]"):
            arr = np.asarray(doc.getArray(f"{base}.{name}[]"), dtype=np.float64)
            if arr.ndim == member.ndim + 1 and arr.shape[-1] == 1:
                arr = arr[..., 0]                   # a one-member class, e.g. {psi: float}
            fields[name] = arr
    saved = Saved(kind, int(step) + 1, float(time), table, fields,       # ts + 1 steps done
                  particle_struct=_sparticle_type(doc, kind))
    path = state_path(input_path)
    mine = saved.text_fingerprint = saved.fingerprint()
    if os.path.lexists(path):
        try:
            state = _read_state(path)
        except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as e:
            saved.state_damaged = (e.strerror if isinstance(e, OSError) and e.strerror
                                   else str(e) or type(e).__name__)
            return saved
        if str(state.pop("fingerprint", "")) == mine:
            for k in [k for k in state if k.startswith(FIELD_PREFIX)]:
                saved.fields.setdefault(k[len(FIELD_PREFIX):], state.pop(k))
            saved.exact = {k: _decode(v) for k, v in state.items() if not k.startswith(_CK)}
        elif str(state.get(_CK + "base", "")) == mine:
            ck_kind, step, time, table, fields, exact = _split_checkpoint(state)
            if same_kind(ck_kind, kind) and step >= saved.step:
                saved = Saved(kind, step, time, table, fields, exact,
                              particle_struct=saved.particle_struct,
                              checkpoint_of=saved.step, text_fingerprint=mine)
    return saved


def _read_state(path):
    """The arrays of a state file; raises for a file that is not one (damaged, empty,
    truncated, a directory)."""
    with open_regular(path) as fh:
        z = np.load(fh, allow_pickle=False)
        if not hasattr(z, "files"):
            raise ValueError("not an .npz archive")
        with z:
            return {k: z[k] for k in z.files}




def wavenumbers(shape, dx):
    """k_x (NX,1,1), k_y (1,NY,1), k_z (1,1,NZ/2+1) of the r2c transform as the original
    numbers them: 2 pi n / L, n = 0..N/2 then negative (N/2 positive)."""
    ks = []
    for n in shape[:2]:
        m = np.fft.fftfreq(n, 1.0 / n)
        if n % 2 == 0:
            m[n // 2] = n // 2
        ks.append(2 * np.pi * m / (n * dx))
    ks.append(2 * np.pi * np.fft.rfftfreq(shape[2], 1.0 / shape[2]) / (shape[2] * dx))
    return ks[0].reshape(-1, 1, 1), ks[1].reshape(1, -1, 1), ks[2].reshape(1, 1, -1)


PACK_NUMBERS = 1 << 18     # modes per block of pack_zeta


def pack_zeta(u_hat: np.ndarray, dx: float, sheared: bool = False):
    """(Zeta (NX, NY, NZ + 2, 2), uk_dc (3,)) of u_hat (3, NX, NY, NZ/2 + 1), the
    unnormalised r2c transform of the velocity (Cartesian; covariant oblique components
    for ``sheared``), in the original's packing (module docstring).  Per mode:

        n_x != 0:                     zeta0 = omega_y, zeta1 = omega_z
        n_x = 0, n_y != 0 (n_z != 0 sheared):  omega_z, omega_x  (sheared: omega_y, omega_x)
        otherwise:                    omega_x, omega_y   (sheared: omega_x, omega_z)
    """
    u = np.asarray(u_hat)
    kx_all, ky, kz = wavenumbers(u.shape[1:3] + (2 * (u.shape[3] - 1),), dx)
    zeta = np.empty(u.shape[1:3] + (2 * u.shape[3], 2))
    # in blocks of x planes (the same element-wise operations): the temporaries are a block's,
    # not ten complex fields of the whole mesh at once (issue 25: the restart's peak memory)
    step = max(1, PACK_NUMBERS // max(1, u[0, 0].size))
    for s in range(0, u.shape[1], step):
        ub, kx = u[:, s:s + step], kx_all[s:s + step]
        wx = 1j * (ky * ub[2] - kz * ub[1])
        wy = 1j * (kz * ub[0] - kx * ub[2])
        wz = 1j * (kx * ub[1] - ky * ub[0])
        a = np.broadcast_to(kx != 0, wx.shape)
        b = np.broadcast_to((kz if sheared else ky) != 0, wx.shape)
        if sheared:
            z0 = np.where(a, wy, np.where(b, wy, wx))
            z1 = np.where(a, wz, np.where(b, wx, wz))
        else:
            z0 = np.where(a, wy, np.where(b, wz, wx))
            z1 = np.where(a, wz, np.where(b, wx, wy))
        for c, w in enumerate((z0, z1)):
            zeta[s:s + step, :, 0::2, c] = w.real
            zeta[s:s + step, :, 1::2, c] = w.imag
    return zeta, u[:, 0, 0, 0].real.copy()


def unpack_zeta(zeta: np.ndarray, uk_dc, dx: float, sheared: bool = False) -> np.ndarray:
    """u_hat (3, NX, NY, NZ/2 + 1) from the original's Zeta (NX, NY, NZ + 2, 2) and uk_dc
    (inverse of :func:`pack_zeta`): the missing vorticity component from k.omega = 0, then
    u^ = i k x omega / |k|^2, u^(0) = uk_dc.  Exact for a solenoidal field (for
    ``sheared``, solenoidal up to a gradient: the caller applies the metric projection)."""
    zeta = np.asarray(zeta, dtype=float)
    nx, ny, nk = zeta.shape[:3]
    if nk % 2 or zeta.shape[3:] != (2,):
        raise ValueError(f"Zeta has shape {zeta.shape}, expected (NX, NY, NZ + 2, 2)")
    z0 = zeta[:, :, 0::2, 0] + 1j * zeta[:, :, 1::2, 0]
    z1 = zeta[:, :, 0::2, 1] + 1j * zeta[:, :, 1::2, 1]
    kx, ky, kz = wavenumbers((nx, ny, nk - 2), dx)
    shape = z0.shape
    a = np.broadcast_to(kx != 0, shape)
    kb = kz if sheared else ky
    b = np.broadcast_to(kb != 0, shape) & ~a
    c = ~(a | b)
    safe_kx = np.where(kx != 0, kx, 1.0)
    safe_kb = np.where(kb != 0, kb, 1.0)
    w = np.zeros((3,) + shape, dtype=complex)
    # n_x != 0: omega_y, omega_z stored, omega_x = -(k_y omega_y + k_z omega_z) / k_x
    w[1] = np.where(a, z0, 0.0)
    w[2] = np.where(a, z1, 0.0)
    w[0] = np.where(a, -(ky * z0 + kz * z1) / safe_kx, 0.0)
    if sheared:     # n_z != 0: omega_y, omega_x; omega_z = -(k_y / k_z) omega_y
        w[1] += np.where(b, z0, 0.0)
        w[0] += np.where(b, z1, 0.0)
        w[2] += np.where(b, -(ky / safe_kb) * z0, 0.0)
        w[0] += np.where(c, z0, 0.0)
        w[2] += np.where(c, z1, 0.0)
    else:           # n_y != 0: omega_z, omega_x; omega_y = -(k_z / k_y) omega_z
        w[2] += np.where(b, z0, 0.0)
        w[0] += np.where(b, z1, 0.0)
        w[1] += np.where(b, -(kz / safe_kb) * z0, 0.0)
        w[0] += np.where(c, z0, 0.0)
        w[1] += np.where(c, z1, 0.0)
    k2 = kx * kx + ky * ky + kz * kz
    inv = np.divide(1.0, k2, out=np.zeros(k2.shape), where=k2 > 0)
    u = np.empty_like(w)
    u[0] = 1j * (ky * w[2] - kz * w[1]) * inv
    u[1] = 1j * (kz * w[0] - kx * w[2]) * inv
    u[2] = 1j * (kx * w[1] - ky * w[0]) * inv
    u[:, 0, 0, 0] = np.asarray(uk_dc, dtype=float).reshape(3)
    return u


# The original fills its restart after the velocity update of the last step has moved
# every force to its *_previous member and zeroed the current one (particle_solver.cxx
# reset_Forces): "fr" is 0 and "fr_previous" holds the step's other force, which the next
# step's Adams-Bashforth update needs (motion.update_velocities).  kapsel-py's state keeps
# the step's forces in f_r, f_hydro, ... (and the records show those); the restart table
# is written and read in the original's convention, so either program continues the
# other's restart.
RESET_PAIRS = {"f_hydro": ("f_hydro", "f_hydro_previous"), "f_r": ("fr", "fr_previous"),
               "f_slip": ("f_slip", "f_slip_previous"),
               "torque_hydro": ("torque_hydro", "torque_hydro_previous"),
               "torque_r": ("torque_r", "torque_r_previous"),
               "torque_slip": ("torque_slip", "torque_slip_previous")}


class _AfterReset:
    """A view of a ParticleState with the forces as the original holds them after a step:
    the current ones 0, the step's in *_previous."""

    def __init__(self, p, names):
        self._p = p
        self.n = p.n
        self._names = names

    def __getattr__(self, name):
        p = self._p
        for attr, (cur, prev) in RESET_PAIRS.items():
            if prev not in self._names:     # an older define.udf: no *_previous member
                continue
            if name == attr or name == OUT_FIELDS.get(cur):
                return np.zeros_like(getattr(p, attr))
            if name == attr + "_previous" or name == OUT_FIELDS.get(prev):
                return getattr(p, attr)
        return getattr(p, name)


def saved_rows(particles):
    """What Saved_Data.Particles[] holds a row of: every particle, or with rigid bodies
    every body (their ``restart_rows``, as the original's resume.cxx writes them)."""
    rows = getattr(getattr(particles, "constraints", None), "restart_rows", None)
    return particles if rows is None else rows()


def restart_table(state, struct) -> np.ndarray:
    """The sParticle table of a restart (the original's convention, ``RESET_PAIRS``)."""
    return _record_table(_AfterReset(state, {m.name for m in struct.members}), struct)


particle_table = restart_table


def particles_from_table(state, table: np.ndarray, struct) -> None:
    """Fill a ParticleState from a (N, leaves) sParticle table (inverse of particle_table).
    The table's rows must match the state's particle count."""
    from udf.schema import leaf_slice
    if table.shape[0] != state.n:
        raise ValueError(f"the restart holds {table.shape[0]} particles, the input "
                         f"describes {state.n}")
    done = set()
    names = {m.name for m in struct.members}

    def column(name):
        off, cnt, _ = leaf_slice(struct, [name])
        return table[:, off:off + cnt]
    # a restart of kapsel-py before 2026-12 kept the step's forces in the current members
    # (fr etc.); the original's and kapsel-py's since then hold 0 there
    current = [cur for cur, prev in RESET_PAIRS.values() if cur in names and prev in names]
    after_reset = not any(np.any(column(c) != 0.0) for c in current)
    for attr, (cur, prev) in RESET_PAIRS.items():
        if after_reset and prev in names:
            getattr(state, attr)[:] = column(prev)
            getattr(state, attr + "_previous")[:] = 0.0
            done.update((attr, attr + "_previous"))
    for m in struct.members:
        attr = OUT_FIELDS.get(m.name)
        if attr is None or attr in done or m.name in ("f_hydro1", "torque_hydro1"):
            continue
        getattr(state, attr)[:] = column(m.name)
        done.add(attr)
