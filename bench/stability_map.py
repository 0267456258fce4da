"""Stability map (issue 17): for each scheme, the largest stable time-step factor, found by
bisection, and what a run does just past it.

    .venv/bin/python bench/stability_map.py [--steps 200] [--refine 2] [--only NAME ...]
                                            [--out bench/results/stability_map.txt]

Every probe is a real ``kapsel-py`` run of the manual's sample (samples/input.udf) shrunk to
16^3 (particle scenes: 2 particles of A = 4, XI = 2, LJ 12:6 EPSILON 5), with
``time_increment.auto.factor`` = f, for --steps steps (output every 20 steps, so the fields
and the restart are written ten times).  A probe is

* ``stable``    exit 0 and every number in output.udf, restart.udf, its state file and the
                HDF5 field files finite;
* ``stopped``   exit 1 with kapsel-py's message (the run stopped at step n: what went out of
                bounds; or the initial state is already past the CFL limit), nothing
                non-finite written;
* ``refused``   exit 2 before the first step: the input check refuses the time step (the
                explicit MAC scheme's diffusion limit), nothing written;
* ``GARBAGE``   a non-finite number in any file the run wrote, or in what it printed on
                stdout (the sheared types' stress table, which users redirect to a file),
                whatever the exit code;
* ``crash``     any other exit (a traceback: a bug);
* ``timeout``   still running after --timeout s (an implicit solver iterating to its maximum
                every step): counted as unstable.

Search: from f = 1, multiply (or divide) by 4 until the outcome changes (f within [1/64,
64]), then --refine geometric bisections of the bracket [largest stable, smallest unstable]
(with the default 2 the bracket's ends differ by a factor 4^(1/4) = 1.41).  "Stable"
means that many steps ran without a stop: a slowly growing mode near the limit may need
longer runs to show.  The table lists the bracket, the dt it means (auto dt = f / (NU KMAX2),
kapsel.timestep), and the outcome at the smallest unstable factor probed.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import multiprocessing
import os
import platform
import re
import shutil
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, ROOT)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

SAMPLES = os.path.join(ROOT, "samples")
NS_CH = "constitutive_eq.Navier_Stokes_Cahn_Hilliard_FDM"
LE_CH = "constitutive_eq.Shear_NS_LE_CH_FDM"


class Scene:
    """One row: a type and the items set on the sample input (dotted UDF paths)."""

    def __init__(self, name, eq, npx=4, particles=0, kBT=0.0, items=None):
        self.name, self.eq, self.npx, self.particles, self.kBT = name, eq, npx, particles, kBT
        self.items = dict(items or {})

    def write(self, d, factor, steps):
        from udf import UDFManager
        os.makedirs(d, exist_ok=True)
        for f in ("define.udf", "kapsel_unit.udf"):
            shutil.copy(os.path.join(SAMPLES, f), os.path.join(d, f))
        u = UDFManager(os.path.join(SAMPLES, "input.udf"))
        u.put(self.eq, "constitutive_eq.type")
        for k in ("NPX", "NPY", "NPZ"):
            u.put(self.npx, f"mesh.{k}")
        u.put(self.kBT, f"constitutive_eq.{self.eq}.kBT")
        u.put(self.particles, "object_type.spherical_particle.Particle_spec[0].Particle_number")
        u.put("auto", "time_increment.type")
        u.put(float(factor), "time_increment.auto.factor")
        gts = 20
        u.put(gts, "output.GTS")
        u.put(max(1, steps // gts), "output.Num_snap")
        for path, value in self.items.items():
            u.put(value, path)
        u.write(os.path.join(d, "input.udf"))

    def dt(self, factor):
        from kapsel.timestep import auto_dt
        n = 2 ** self.npx
        return auto_dt(factor, 1.0, 1.0, 1.0, (n, n, n))


def _shear(eq, rate, **kw):
    return {f"constitutive_eq.{eq}.External_field.type": "DC",
            f"constitutive_eq.{eq}.External_field.DC.Shear_rate": float(rate), **kw}


def scenes():
    rows = [
        Scene("spectral NS, 2 particles, kBT 1", "Navier_Stokes", particles=2, kBT=1.0),
        Scene("MAC explicit, 2 particles, kBT 1", "Navier_Stokes_FDM", particles=2,
              kBT=1.0, items={"constitutive_eq.Navier_Stokes_FDM.NS_solver.type":
                              "explicit_scheme"}),
        Scene("MAC implicit, 2 particles, kBT 1", "Navier_Stokes_FDM", particles=2,
              kBT=1.0, items={"constitutive_eq.Navier_Stokes_FDM.NS_solver.type":
                              "implicit_scheme"}),
    ]
    for ch, label in (("explicit_scheme", "CH explicit"), ("implicit_scheme", "CH BDF2")):
        for pot in ("Landau", "Flory_Huggins"):
            rows.append(Scene(f"{label} ({pot}), MAC implicit, spinodal",
                              "Navier_Stokes_Cahn_Hilliard_FDM",
                              items={f"{NS_CH}.NS_solver.type": "implicit_scheme",
                                     f"{NS_CH}.CH_solver.type": ch,
                                     f"{NS_CH}.Potential.type": pot}))
        rows.append(Scene(f"{label} (Landau), MAC implicit, 2 particles",
                          "Navier_Stokes_Cahn_Hilliard_FDM", particles=2,
                          items={f"{NS_CH}.NS_solver.type": "implicit_scheme",
                                 f"{NS_CH}.CH_solver.type": ch}))
    rows.append(Scene("CH explicit (Landau), MAC explicit, spinodal",
                      "Navier_Stokes_Cahn_Hilliard_FDM",
                      items={f"{NS_CH}.NS_solver.type": "explicit_scheme",
                             f"{NS_CH}.CH_solver.type": "explicit_scheme"}))
    for rate in (0.1, 1.0):
        eq = "Shear_Navier_Stokes_Lees_Edwards"
        rows.append(Scene(f"Lees-Edwards spectral, shear {rate:g}, 2 particles", eq,
                          particles=2, items=_shear(eq, rate)))
    for rate in (0.1, 1.0):
        eq = "Shear_Navier_Stokes_Lees_Edwards_FDM"
        rows.append(Scene(f"Lees-Edwards MAC implicit, shear {rate:g}, 2 particles", eq,
                          particles=2,
                          items=_shear(eq, rate, **{f"constitutive_eq.{eq}.NS_solver.type":
                                                    "implicit_scheme"})))
    eq = "Shear_Navier_Stokes"
    rows.append(Scene("zigzag shear spectral, shear 0.1, 2 particles", eq, particles=2,
                      items=_shear(eq, 0.1)))
    rows.append(Scene("Lees-Edwards CH BDF2 (Landau), shear 0.1", "Shear_NS_LE_CH_FDM",
                      items=_shear("Shear_NS_LE_CH_FDM", 0.1, **{
                          f"{LE_CH}.NS_solver.type": "implicit_scheme",
                          f"{LE_CH}.CH_solver.type": "implicit_scheme"})))
    return rows


# ---------------------------------------------------------------------- one probe
_NUM = re.compile(rb"(?<![A-Za-z_])[-+]?(nan|inf|infinity)(?![A-Za-z_])", re.IGNORECASE)


def nonfinite_files(d):
    """The files under d holding a NaN or infinity (UDF text, npz, HDF5)."""
    bad = []
    for root, _, files in os.walk(d):
        for name in files:
            path = os.path.join(root, name)
            if name in ("input.udf", "define.udf", "kapsel_unit.udf", "stderr.txt"):
                continue
            try:
                if name.endswith(".npz"):
                    with np.load(path, allow_pickle=False) as z:
                        if any(z[k].dtype.kind in "fc" and not np.isfinite(z[k]).all()
                               for k in z.files):
                            bad.append(name)
                elif name.endswith((".h5", ".hdf5")):
                    import h5py
                    found = []

                    def visit(_, obj):
                        if isinstance(obj, h5py.Dataset) and obj.dtype.kind in "fc":
                            if not np.isfinite(obj[()]).all():
                                found.append(obj.name)
                    with h5py.File(path, "r") as f:
                        f.visititems(visit)
                    if found:
                        bad.append(name)
                elif name.endswith((".udf", ".dat", ".txt", ".fld", ".xmf")):
                    with open(path, "rb") as f:
                        if _NUM.search(f.read()):
                            bad.append(name)
            except Exception as e:           # noqa: BLE001 - an unreadable file is garbage
                bad.append(f"{name} (unreadable: {type(e).__name__})")
    return bad


def _child(d, conn):
    os.chdir(d)
    fd = os.open("stderr.txt", os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
    os.dup2(fd, 2)
    sys.stderr = io.TextIOWrapper(os.fdopen(2, "wb", buffering=0), write_through=True)
    from kapsel.cli import main
    try:
        with open("stdout.txt", "w") as out, contextlib.redirect_stdout(out):
            rc = main(["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                       "--seed", "1", "--quiet", "--overwrite"])
    except SystemExit as e:
        rc = e.code if isinstance(e.code, int) else 2
    except BaseException:                    # noqa: BLE001 - a crash is an outcome
        import traceback
        traceback.print_exc()
        rc = 99
    sys.stderr.flush()
    conn.send(rc)
    os._exit(0)


def probe(scene, factor, steps, timeout, workdir):
    d = os.path.join(workdir, f"f{factor:.6g}")
    shutil.rmtree(d, ignore_errors=True)
    scene.write(d, factor, steps)
    ctx = multiprocessing.get_context("fork")
    a, b = ctx.Pipe(duplex=False)
    t0 = time.perf_counter()
    proc = ctx.Process(target=_child, args=(d, b))
    proc.start()
    rc = None
    if a.poll(timeout):
        rc = a.recv()
    proc.join(5)
    if proc.is_alive():
        proc.kill()
        proc.join()
    sec = time.perf_counter() - t0
    try:
        with open(os.path.join(d, "stderr.txt")) as f:
            err = f.read()
    except OSError:
        err = ""
    bad = nonfinite_files(d)
    msg = next((ln[len("kapsel-py: error: "):] for ln in err.splitlines()
                if ln.startswith("kapsel-py: error: ")), err.strip().splitlines()[-1:] or [""])
    msg = msg if isinstance(msg, str) else msg[0]
    if bad:
        kind = "GARBAGE"
    elif rc is None:
        kind = "timeout"
    elif "Traceback" in err:
        kind = "crash"
    elif rc == 0:
        kind = "stable"
    elif rc == 1 and "kapsel-py: error: " in err:
        kind = "stopped"
    elif rc == 2 and "time step" in msg and not os.path.exists(os.path.join(d, "output.udf")):
        kind = "refused"
    else:
        kind = "crash"
    return dict(factor=factor, dt=scene.dt(factor), kind=kind, rc=rc, message=msg,
                garbage=bad, sec=round(sec, 1))


def search(scene, steps, refine, timeout, workdir, log):
    probes = {}

    def run(f):
        r = probe(scene, f, steps, timeout, workdir)
        probes[f] = r
        log(f"  f={f:<9.4g} dt={r['dt']:<9.4g} {r['kind']:<8} {r['sec']:5.1f} s  "
            f"{r['message'][:100]}")
        return r["kind"] == "stable"

    lo = hi = None
    f = 1.0
    if run(f):
        lo = f
        while hi is None and f < 64:
            f *= 4
            if run(f):
                lo = f
            else:
                hi = f
    else:
        hi = f
        while lo is None and f > 1 / 64:
            f /= 4
            if run(f):
                lo = f
            else:
                hi = f
    if lo is not None and hi is not None:
        for _ in range(refine):
            mid = math.sqrt(lo * hi)
            if run(mid):
                lo = mid
            else:
                hi = mid
    past = probes[hi] if hi is not None else None
    return dict(scene=scene.name, eq=scene.eq, mesh=2 ** scene.npx, lo=lo, hi=hi,
                dt_lo=scene.dt(lo) if lo else None, dt_hi=scene.dt(hi) if hi else None,
                past=past, probes=[probes[k] for k in sorted(probes)])


def outcome(p):
    """One table cell: the kind, the message's first clause, the step the restart holds."""
    if p["kind"] == "timeout":
        return f"timeout: still running after {p['sec']:.0f} s"
    first = re.split(r"\. (?=[A-Z]|restart|No )|; ", p["message"])[0]
    text = f"{p['kind']}: {first}"
    m = re.search(r"holds the last good state \(step (\d+)\)", p["message"])
    if m:
        text += f"; restart.udf holds step {m.group(1)}"
    if p["garbage"]:
        text += f" [non-finite in {', '.join(p['garbage'])}]"
    return text.replace("|", "\\|")


def table(results):
    lines = ["| scheme / scene | mesh | largest stable factor (bracket) | dt bracket "
             "| just past the limit |",
             "|---|---|---|---|---|"]
    for r in results:
        lo = f"{r['lo']:.3g}" if r["lo"] is not None else "< 1/64"
        hi = f"{r['hi']:.3g}" if r["hi"] is not None else "none unstable"
        dlo = f"{r['dt_lo']:.3g}" if r["dt_lo"] else "-"
        dhi = f"{r['dt_hi']:.3g}" if r["dt_hi"] else "-"
        if r["past"] is None:
            past = "-"
        else:
            past = outcome(r["past"])
        lines.append(f"| {r['scene']} | {r['mesh']}^3 | [{lo}, {hi}] | [{dlo}, {dhi}] "
                     f"| {past} |")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--refine", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=60.0,
                    help="seconds after which a probe counts as failed (an implicit solver "
                         "iterating to its maximum every step)")
    ap.add_argument("--only", nargs="*", default=None, help="scenes whose name contains any")
    ap.add_argument("--out", default=os.path.join(HERE, "results", "stability_map.txt"))
    a = ap.parse_args()
    rows = [s for s in scenes() if not a.only or any(k in s.name for k in a.only)]
    from kapsel import models
    from kapsel.mesh import compiled  # noqa: F401  (loaded once, shared by the probes)
    compiled.enable()
    t0 = time.perf_counter()
    results = []
    with tempfile.TemporaryDirectory(prefix="kapsel-stability-") as work:
        for s in rows:
            print(f"{s.name} ({s.eq}, {2 ** s.npx}^3):", flush=True)
            results.append(search(s, a.steps, a.refine, a.timeout,
                                  os.path.join(work, re.sub(r"\W+", "_", s.name)),
                                  lambda m: print(m, flush=True)))
    total = time.perf_counter() - t0
    head = (f"Stability map, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
            f"{platform.node()} ({os.cpu_count()} cores, load average "
            f"{os.getloadavg()[0]:.1f}), {a.steps} steps per probe, {total:.0f} s")
    text = head + "\n\n" + table(results) + "\n"
    print("\n" + text)
    if a.out:
        os.makedirs(os.path.dirname(a.out), exist_ok=True)
        with open(a.out, "w") as f:
            f.write(text)
        with open(os.path.splitext(a.out)[0] + ".json", "w") as f:
            json.dump(dict(header=head, results=results), f, indent=1)
    garbage = [r["scene"] for r in results
               if any(p["kind"] in ("GARBAGE", "crash") for p in r["probes"])]
    if garbage:
        print(f"WRONG: garbage written or crashed in: {', '.join(garbage)}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
