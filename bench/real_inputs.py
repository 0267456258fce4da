"""Every real KAPSEL input run by the original and by kapsel-py, side by side (issue 24).

    .venv/bin/python bench/real_inputs.py [--kref PATH] [--kref-tools DIR] [--steps 200]
        [--records 10] [--steps-of NAME=N ...] [--only NAME ...] [--out DIR]
        [--reuse-original] [--table]
    .venv/bin/python bench/real_inputs.py --check [--only NAME ...] [--out DIR]

The inputs are those of ``samples/kapsel-udf/*/`` (the original's examples and sample:
ex01 ex02 ex06 ex09 ex10 ex11 ex12 ex13 ex14 sample).  Each is run for ``--steps`` steps
(default 200, or its own length if shorter; ``--steps-of ex02=4`` for one input) with one
record every steps / ``--records`` steps: only ``output:{GTS, Num_snap}`` of the input text is
edited, nothing else.  Both programs run on one thread (OMP_NUM_THREADS=1; kapsel-py
``--threads 1 --seed 1``), one after the other, in ``OUT/<name>/original`` and
``OUT/<name>/kapsel-py``; the table gives for each input its type, mesh, particles, steps,
the exit code, wall time and peak RSS of both, and their agreement:

* deterministic starts (user_specify positions or no particles, no thermal noise, no random
  orientation or order-parameter noise): at the last common record, max|dR| / motion
  (minimum-image position difference over the largest displacement from the start) and
  max|dv| / max|v| (over the original's largest speed);
* random starts: rms(|v|) of kapsel-py over the original's, per record (the range over the
  records after the first; 1 is agreement in magnitude only).

The original is the kref build of kapsel3 (``/work/shared/kref/README.md``: ``build.sh``
builds ``$KREF/src/kapsel`` reading *flattened* inputs; ``flatten_udf.py`` writes them).
Its binary comes from ``--kref`` or ``$KREF_CPP``, the tools from ``--kref-tools`` or
``$KREF_TOOLS``; without them only kapsel-py runs (``--no-original``) or the script says how
to build it.  Results go to ``OUT/results.jsonl`` (one line per input, appended) and the
table is printed at the end (``--table``: print the table of OUT's results and exit).
``--reuse-original`` keeps the original's run of an input already in OUT (it does not depend
on kapsel-py).

``--check``: ``kapsel-py --check`` of every input unchanged (no field work), and of a 256^3
``Electrolyte`` input with 10 000 spheres (ex01 with mesh 8 8 8, A = 4, Particle_number
10000, placed by each of uniform_random, FCC, BCC and random_walk): a table of the exit
code, wall and CPU seconds and peak RSS of each.

Peak RSS is the child's ru_maxrss and CPU its user + system time (os.wait4), wall time from
start to exit of the process (on a shared machine the CPU time is the better measure).
"""
from __future__ import annotations

import argparse
import glob
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

REAL = ROOT / "samples" / "kapsel-udf"
_OUTPUT = re.compile(r"^(output:\s*\{\s*)(\d+)(\s*,(?:\s*//[^\n]*)?\s*)(\d+)", re.M)


def inputs():
    """name -> path of every real input (ex06 has two: ex06/s000..., ex06/s001...)."""
    out = {}
    for p in sorted(REAL.glob("*/*.udf")):
        if p.name in ("define.udf", "kapsel_unit.udf"):
            continue
        d = p.parent.name
        many = len([q for q in p.parent.glob("*.udf")
                    if q.name not in ("define.udf", "kapsel_unit.udf")]) > 1
        out[f"{d}/{p.stem}" if many else d] = p
    return out


def set_output(text: str, gts: int, nsnap: int) -> str:
    """The input text with output:{GTS, Num_snap} replaced (the only edit)."""
    new, n = _OUTPUT.subn(lambda m: f"{m.group(1)}{gts}{m.group(3)}{nsnap}", text, count=1)
    if not n:
        raise SystemExit("no output:{GTS, Num_snap} in the input")
    return new


def describe(path: Path) -> dict:
    """Type, mesh, particles, own length and whether the start is deterministic, from
    kapsel-py's reading of the input."""
    from kapsel import cli
    cfg, _, _ = cli.validate(str(path))
    p, sw = cfg.particles, cfg.switches
    n = p.count
    if p.object_type == "spherical_particle":
        what = f"{n}"
    else:
        groups = sum(s.number for s in p.species)
        what = f"{groups} {'chains' if p.object_type == 'chain' else 'bodies'} ({n} beads)"
    noise = cfg.fluid.kBT > 0 and cfg.type != "Electrolyte"
    oriented = p.object_type == "rigid" or sw.dipoles is not None or any(
        getattr(s.janus, "propulsion", "OFF") not in ("OFF", None) for s in p.species)
    random_q = sw.init_orientation == "random" and oriented
    placed = n == 0 or sw.init_distribution == "user_specify"
    psi_noise = cfg.phase is not None and cfg.phase.initial_fluctuation > 0
    return {"type": cfg.type, "mesh": "x".join(map(str, cfg.mesh.shape)), "particles": what,
            "n": n, "own_steps": cfg.output.total_steps,
            "deterministic": bool(placed and not noise and not random_q and not psi_noise)}


def run(cmd, cwd, env, timeout):
    """(exit code, wall s, CPU s, peak RSS bytes, stderr tail) of one process."""
    t0 = time.perf_counter()
    with open(os.path.join(cwd, "stdout.txt"), "w") as out, \
            open(os.path.join(cwd, "stderr.txt"), "w") as err:
        proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=out, stderr=err)
        try:
            _, status, usage = _wait4(proc, timeout)
            code = os.waitstatus_to_exitcode(status)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, status, usage = os.wait4(proc.pid, 0)
            code = "timeout"
    wall = time.perf_counter() - t0
    proc.returncode = code if isinstance(code, int) else -9
    tail = Path(cwd, "stderr.txt").read_text(errors="replace").strip().splitlines()[-3:]
    cpu = usage.ru_utime + usage.ru_stime
    return code, wall, cpu, usage.ru_maxrss * 1024, " | ".join(tail)[-300:]


def _wait4(proc, timeout):
    end = time.monotonic() + timeout
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            return pid, status, usage
        if time.monotonic() > end:
            raise subprocess.TimeoutExpired(proc.args, timeout)
        time.sleep(0.2)


# ----------------------------------------------------------------------------- records
def original_records(path):
    """t, R, v per record of the original's flat output (the kref stand-in writes every
    put() as 'record<TAB>path<TAB>value')."""
    rec = {}
    pat = re.compile(r"^Particles\[(\d+)\]\.(R|v)\.([xyz])$")
    with open(path) as fh:
        for line in fh:
            if line.startswith("#"):
                continue
            parts = line.rstrip("\n").split("\t", 2)
            if len(parts) != 3:
                continue
            r, p, v = parts
            r = int(r)
            if r < 0:
                continue
            d = rec.setdefault(r, {"t": None, "R": {}, "v": {}})
            if p == "t":
                d["t"] = float(v)
                continue
            m = pat.match(p)
            if m:
                d[m.group(2)][(int(m.group(1)), "xyz".index(m.group(3)))] = float(v)
    out = {"t": [], "R": [], "v": []}
    for r in sorted(rec):
        d = rec[r]
        out["t"].append(d["t"])
        for k in ("R", "v"):
            n = 1 + max((i for i, _ in d[k]), default=-1)
            a = np.zeros((n, 3))
            for (i, c), x in d[k].items():
                a[i, c] = x
            out[k].append(a)
    return out


def py_records(path):
    from udf import UDFManager
    u = UDFManager(str(path))
    out = {"t": [], "R": [], "v": []}
    for r in range(u.totalRecord()):
        u.jump(r)
        out["t"].append(float(u.get("t")))
        for k in ("R", "v"):
            try:
                out[k].append(np.asarray(u.getArray(f"Particles[].{k}"), float).reshape(-1, 3))
            except Exception:
                out[k].append(np.zeros((0, 3)))
    return out


def agreement(c, p, box, deterministic):
    """The agreement of the records of the original (c) and kapsel-py (p) at common steps."""
    tc = {t: i for i, t in enumerate(c["t"])}
    common = [(tc[t], j, t) for j, t in enumerate(p["t"]) if t in tc]
    if not common:
        return {"common_records": 0}
    n = min(len(c["R"][common[0][0]]), len(p["R"][common[0][1]]))
    res = {"common_records": len(common), "last_common_step": int(common[-1][2])}
    if n == 0:
        return res
    L = np.asarray(box, float)

    def mi(d):
        return d - L * np.round(d / L)
    if deterministic:
        i, j, _ = common[-1]
        i0 = common[0][0]
        dR = np.linalg.norm(mi(p["R"][j][:n] - c["R"][i][:n]), axis=1).max()
        motion = np.linalg.norm(mi(c["R"][i][:n] - c["R"][i0][:n]), axis=1).max()
        dv = np.linalg.norm(p["v"][j][:n] - c["v"][i][:n], axis=1).max()
        vmax = np.linalg.norm(c["v"][i][:n], axis=1).max()
        res.update(dR=float(dR), motion=float(motion), dv=float(dv), vmax=float(vmax),
                   dR_rel=float(dR / motion) if motion > 0 else None,
                   dv_rel=float(dv / vmax) if vmax > 0 else None)
    else:
        ratios = []
        for i, j, t in common[1:]:          # (the start: at rest, or the original's kick)
            rc = math.sqrt(float(np.mean(np.sum(c["v"][i][:n] ** 2, axis=1))))
            rp = math.sqrt(float(np.mean(np.sum(p["v"][j][:n] ** 2, axis=1))))
            if rc > 0:
                ratios.append(rp / rc)
        if ratios:
            res.update(speed_ratio_last=ratios[-1], speed_ratio_min=min(ratios),
                       speed_ratio_max=max(ratios))
    return res


def field_agreement(dc, dp):
    """FDM types, at the last snapshot both wrote: the rms of u minus its mean
    (velocity_<n>.h5) and the std of psi (orderparam_<n>.h5) of kapsel-py over the
    original's, and each program's |mean u| (a drift of the whole fluid)."""
    import h5py

    def snaps(d, stem):
        return {int(f.stem.rsplit("_", 1)[1]): f for f in d.glob(f"{stem}_*.h5")}
    res = {}
    for stem, key in (("velocity", "u_rms_ratio"), ("orderparam", "psi_std_ratio")):
        a, b = snaps(dc, stem), snaps(dp, stem)
        both = sorted(set(a) & set(b))
        if not both:
            continue
        vals = []
        for side, f in (("orig", a[both[-1]]), ("py", b[both[-1]])):
            with h5py.File(f, "r") as h:
                if stem == "velocity":
                    u = [h[k][...] for k in ("UX", "UY", "UZ")]
                    vals.append(math.sqrt(sum(float(np.var(c)) for c in u)))
                    res[f"u_mean_{side}"] = math.sqrt(sum(float(np.mean(c)) ** 2
                                                          for c in u))
                else:
                    key_psi = "PSI_ALL" if "PSI_ALL" in h else "PSI"
                    vals.append(float(np.std(h[key_psi][...])))
        if vals[0] > 0:
            res[key] = vals[1] / vals[0]
            res[f"{stem}_snapshot"] = both[-1]
    return res


def compare(path, dc, dp, deterministic):
    """The agreement of the runs in dc (original) and dp (kapsel-py), or None when one of
    them wrote no records."""
    c, p = Path(dc) / "output.flat", Path(dp) / "output.udf"
    if not (c.exists() and p.exists()):
        return None
    from kapsel import cli
    cfg, _, _ = cli.validate(str(path))
    try:
        a = agreement(original_records(c), py_records(p), cfg.mesh.box, deterministic)
        a.update(field_agreement(Path(dc), Path(dp)))
        return a
    except Exception as e:          # a torn file of a crashed run: say so
        return {"error": f"{type(e).__name__}: {e}"}


# ----------------------------------------------------------------------------- one input
def prepare(name, path, steps, records, out):
    info = describe(path)
    n_steps = min(steps, info["own_steps"])
    gts = max(1, n_steps // records)
    nsnap = max(1, -(-n_steps // gts))
    text = set_output(path.read_text(errors="replace"), gts, nsnap)
    dirs = {}
    for side in ("original", "kapsel-py"):
        d = out / name / side
        shutil.rmtree(d, ignore_errors=True) if side == "kapsel-py" else None
        d.mkdir(parents=True, exist_ok=True)
        for f in path.parent.iterdir():
            if f.name in ("define.udf", "kapsel_unit.udf"):
                shutil.copy(f, d / f.name)
        (d / "input.udf").write_text(text)
        dirs[side] = d
    info.update(name=name, steps=gts * nsnap, GTS=gts, Num_snap=nsnap)
    return info, dirs


def run_original(d, cpp, tools, timeout, reuse):
    """The original's run in ``d`` (reused with ``reuse`` if one of the same input text is
    there)."""
    done = d / "done.json"
    text = (d / "input.udf").read_text(errors="replace")
    if reuse and done.exists():
        old = json.loads(done.read_text())
        if old.get("input") == text:
            return old["result"]
    for f in d.iterdir():
        if f.name not in ("input.udf", "define.udf", "kapsel_unit.udf"):
            shutil.rmtree(f) if f.is_dir() else f.unlink()
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    subprocess.run([sys.executable, os.path.join(tools, "flatten_udf.py"), "input.udf",
                    "input.flat"], cwd=d, env=env, check=True, capture_output=True)
    code, wall, cpu, rss, tail = run([cpp, "-Iinput.flat", "-Ooutput.flat", "-Ddefine.udf",
                                      "-Rrestart.flat"], d, env, timeout)
    res = {"code": code, "wall": wall, "cpu": cpu, "rss": rss, "tail": tail}
    done.write_text(json.dumps({"input": text, "result": res}))
    return res


def run_py(d, timeout):
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    code, wall, cpu, rss, tail = run([sys.executable, "-m", "kapsel.cli", "-Iinput.udf",
                                      "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                                      "--threads", "1", "--seed", "1", "--quiet"], d, env,
                                     timeout)
    return {"code": code, "wall": wall, "cpu": cpu, "rss": rss, "tail": tail}


# ----------------------------------------------------------------------------- table
def _gb(b):
    return f"{b / 2 ** 30:.2f} GB" if b >= 2 ** 30 else f"{b / 2 ** 20:.0f} MB"


def _agree(r):
    a = r.get("agreement") or {}
    if "error" in a:
        return a["error"]
    if not a.get("common_records"):
        return "no common records"
    parts = []
    if "dR" in a:
        rel = lambda x: "-" if x is None else f"{x:.2e}"   # noqa: E731
        parts.append(f"dR/motion {rel(a.get('dR_rel'))} (dR {a['dR']:.2e}), "
                     f"dv/vmax {rel(a.get('dv_rel'))} at step {a['last_common_step']}")
    elif "speed_ratio_last" in a:
        parts.append(f"rms speed py/orig {a['speed_ratio_last']:.3f} at step "
                     f"{a['last_common_step']} (records: {a['speed_ratio_min']:.3f}-"
                     f"{a['speed_ratio_max']:.3f})")
    else:
        parts.append(f"{a['common_records']} records, no particle motion to compare")
    if "u_rms_ratio" in a:
        parts.append(f"fluid rms(u - <u>) py/orig {a['u_rms_ratio']:.3f}, |<u>| orig "
                     f"{a['u_mean_orig']:.2e} py {a['u_mean_py']:.2e}")
    if "psi_std_ratio" in a:
        parts.append(f"std psi py/orig {a['psi_std_ratio']:.3f}")
    return "; ".join(parts)


def table(results):
    head = ("| input | type | mesh | particles | steps | exit orig / py | wall orig / py (s) "
            "| CPU orig / py (s) | peak RSS orig / py | start | agreement |")
    lines = [head, "|" + "---|" * 11]

    def sec(d, k):
        return f"{d[k]:.0f}" if k in d else "-"
    for r in results:
        o, p = r.get("original") or {}, r.get("kapsel-py") or {}
        steps = f"{r['steps']}" + ("" if not r.get("why") else f" ({r['why']})")
        lines.append(
            f"| {r['name']} | {r['type']} | {r['mesh']} | {r['particles']} | {steps} | "
            f"{o.get('code', '-')} / {p.get('code', '-')} | "
            f"{sec(o, 'wall')} / {sec(p, 'wall')} | {sec(o, 'cpu')} / {sec(p, 'cpu')} | "
            f"{_gb(o['rss']) if 'rss' in o else '-'} / {_gb(p['rss']) if 'rss' in p else '-'} | "
            f"{'deterministic' if r['deterministic'] else 'random'} | {_agree(r)} |")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- --check
LARGE_ELECTROLYTE = ("uniform_random", "FCC", "BCC", "random_walk")


def large_electrolyte(d: Path, distribution: str) -> Path:
    """ex01 (Electrolyte, salt, Poisson-Boltzmann start, DC field) on a 256^3 mesh with
    10 000 spheres of A = 4 placed by ``distribution`` (the issue-24 case of --check), in
    ``d``."""
    from udf import UDFManager
    src = REAL / "ex01"
    d.mkdir(parents=True, exist_ok=True)
    for f in ("define.udf", "kapsel_unit.udf"):
        if (src / f).exists():
            shutil.copy(src / f, d / f)
    u = UDFManager(str(src / "colloid_1.udf"))
    u.put([8, 8, 8], "mesh")
    u.put(4.0, "A")
    u.put(10_000, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put(distribution, "switch.INIT_distribution.type")
    u.write(str(d / "input.udf"))
    return d / "input.udf"


def check_table(names, out: Path) -> str:
    """``kapsel-py --check`` of each named input (unchanged, in a copy of its directory)
    and of the large Electrolyte cases: exit code, wall and CPU seconds, peak RSS."""
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT),
               KAPSEL_PY_MEMORY_LIMIT_GB="64")   # the inputs, not this machine's memory
    cases = []
    for name in names:
        path = inputs()[name]
        d = out / "check" / name
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir(parents=True)
        for f in path.parent.iterdir():
            if f.is_file():
                shutil.copy(f, d / f.name)
        cases.append((name, d, path.name))
    for dist in LARGE_ELECTROLYTE:
        d = out / "check" / f"electrolyte256-{dist}"
        shutil.rmtree(d, ignore_errors=True)
        cases.append((f"Electrolyte 256^3, 10 000 spheres, {dist}",
                      large_electrolyte(d, dist).parent, "input.udf"))
    lines = ["| input | mesh | particles | exit | wall (s) | CPU (s) | peak RSS | memory "
             "estimate of the run |", "|" + "---|" * 8]
    for label, d, inp in cases:
        code, wall, cpu, rss, _ = run([sys.executable, "-m", "kapsel.cli", f"-I{inp}",
                                       "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                                       "--check"], str(d), env, 600)
        text = Path(d, "stdout.txt").read_text(errors="replace")
        mesh = re.search(r"^mesh (\d+ x \d+ x \d+)", text, re.M)
        parts = re.search(r"^particles: (\d+)", text, re.M)
        est = re.search(r"^memory: about (.+?) \(", text, re.M)
        lines.append(f"| {label} | {mesh.group(1) if mesh else '-'} | "
                     f"{parts.group(1) if parts else 0} | {code} | {wall:.1f} | {cpu:.1f} | "
                     f"{_gb(rss)} | {est.group(1) if est else '-'} |")
        print(lines[-1], file=sys.stderr, flush=True)
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kref", default=os.environ.get("KREF_CPP"),
                    help="the original's binary (kref build; default $KREF_CPP)")
    ap.add_argument("--kref-tools", default=os.environ.get("KREF_TOOLS"),
                    help="the kref tools (flatten_udf.py; default $KREF_TOOLS)")
    ap.add_argument("--no-original", action="store_true", help="run kapsel-py only")
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--records", type=int, default=10)
    ap.add_argument("--steps-of", action="append", default=[], metavar="NAME=N",
                    help="fewer steps for one input (say why with NAME=N:why)")
    ap.add_argument("--only", nargs="*", help="inputs to run (default: all)")
    ap.add_argument("--out", default=os.path.join(tempfile.gettempdir(), "kapsel-real-inputs"),
                    help="work directory (default: $TMPDIR/kapsel-real-inputs)")
    ap.add_argument("--reuse-original", action="store_true")
    ap.add_argument("--timeout", type=float, default=6 * 3600)
    ap.add_argument("--table", action="store_true", help="print OUT's table and exit")
    ap.add_argument("--check", action="store_true",
                    help="time kapsel-py --check of every input and of a 256^3 Electrolyte "
                         "input with 10 000 particles, and exit")
    args = ap.parse_args(argv)
    out = Path(args.out)
    if args.check:
        print(check_table(args.only or list(inputs()), out))
        return 0
    results_file = out / "results.jsonl"
    if args.table:
        latest = {}
        for line in results_file.read_text().splitlines():
            r = json.loads(line)
            latest[r["name"]] = r
        for r in latest.values():            # agreement re-read from the runs' files
            a = compare(inputs()[r["name"]], out / r["name"] / "original",
                        out / r["name"] / "kapsel-py", r["deterministic"])
            if a is not None:
                r["agreement"] = a
        print(table([latest[k] for k in inputs() if k in latest]))
        return 0
    have_original = not args.no_original
    if have_original:
        if not args.kref or not os.access(args.kref, os.X_OK):
            print(f"real_inputs.py: the original's binary {args.kref or '(none given)'} is "
                  f"not there.  Build it with the kref tools (/work/shared/kref/README.md: "
                  f"KREF=<dir> KAPSEL3_GIT=<kapsel3 git dir> build.sh makes "
                  f"$KREF/src/kapsel), then pass --kref $KREF/src/kapsel or set KREF_CPP; or "
                  f"run kapsel-py alone with --no-original", file=sys.stderr)
            return 2
        if not args.kref_tools or not os.path.exists(os.path.join(args.kref_tools,
                                                                  "flatten_udf.py")):
            print(f"real_inputs.py: no flatten_udf.py in --kref-tools "
                  f"{args.kref_tools or '(none given)'} (the kref tools directory, "
                  f"/work/shared/kref here; or set KREF_TOOLS)", file=sys.stderr)
            return 2
    fewer = {}
    for item in args.steps_of:
        name, _, rest = item.partition("=")
        n, _, why = rest.partition(":")
        fewer[name] = (int(n), why or "fewer steps asked")
    all_inputs = inputs()
    names = args.only or list(all_inputs)
    out.mkdir(parents=True, exist_ok=True)
    done = []
    for name in names:
        path = all_inputs[name]
        steps, why = fewer.get(name, (args.steps, ""))
        records = min(args.records, steps)
        info, dirs = prepare(name, path, steps, records, out)
        if why:
            info["why"] = why
        print(f"# {name}: {info['type']} {info['mesh']}, {info['particles']} particles, "
              f"{info['steps']} steps (GTS {info['GTS']})", file=sys.stderr, flush=True)
        if have_original:
            info["original"] = run_original(dirs["original"], args.kref, args.kref_tools,
                                            args.timeout, args.reuse_original)
            print(f"#   original: exit {info['original']['code']}, "
                  f"{info['original']['wall']:.0f} s", file=sys.stderr, flush=True)
        info["kapsel-py"] = run_py(dirs["kapsel-py"], args.timeout)
        print(f"#   kapsel-py: exit {info['kapsel-py']['code']}, "
              f"{info['kapsel-py']['wall']:.0f} s", file=sys.stderr, flush=True)
        if have_original:
            info["agreement"] = compare(path, dirs["original"], dirs["kapsel-py"],
                                        info["deterministic"])
        with open(results_file, "a") as fh:
            fh.write(json.dumps(info) + "\n")
        done.append(info)
    print(table(done))
    return 0


if __name__ == "__main__":
    sys.exit(main())
