"""kapsel-py against the original program (kapsel_u2m) on the scenes of issue 14.

    .venv/bin/python bench/bench_vs_original.py [--scene NAME ...] [--repeat R] [--threads T]
                                                [--keep DIR]

Every scene is built from ``samples/input.udf`` (programmatically, through udf.UDFManager):
kBT 0 (the sample's), ``time_increment`` auto with factor 1, ``output.GTS`` 10, and

    sample        the sample as is (Navier_Stokes_Cahn_Hilliard_FDM 32^3, 8 particles)
    ns32          Navier_Stokes 32^3, 1 particle (A 4)
    ns64          Navier_Stokes 64^3, 1 particle (A 4)
    ns64x100      Navier_Stokes 64^3, 100 particles (A 2)
    fdm64e        Navier_Stokes_FDM explicit_scheme 64^3, 8 particles
    fdm64i        Navier_Stokes_FDM implicit_scheme 64^3, 8 particles
    nsch64        Navier_Stokes_Cahn_Hilliard_FDM 64^3, 8 particles (the sample's solvers)
    le32          Shear_Navier_Stokes_Lees_Edwards 32^3, 8 particles (the sample's DC 0.01)

kapsel-py's figure is the CPU time (user + system, of the child process) of a 60-step run
minus that of a 20-step run, divided by 40, each run a fresh ``python -m kapsel.cli`` with
``--threads 1 --quiet --seed 1`` (start-up, set-up and the first snapshot cancel; the
snapshots every 10 steps are included) and KAPSEL_PY_COMPILED=1 (the compiled kernels from
the start, as a long run has them from step 10 on; kapsel.compiled).  CPU time, not wall
time, because the machine is shared.  With ``--repeat R`` each run is repeated R times and
the smallest CPU time kept.  The original's figures are those of issue 14 (its time loop's
CPU per step, the same machine); the ratio is kapsel-py / original.  Also printed: the CPU
seconds from the start of the process to its first time step ("start-up", default settings),
the peak RSS of the 60-step run, and "step only": the CPU ms of ``model.advance()`` alone, in-process, over
40 steps after 3 warm-up steps (bench/profile_step.py --time-only; no output, no snapshots),
which separates the cost of the step from that of the snapshots (restart.udf, records).
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from udf import UDFManager  # noqa: E402

# name: (label, original ms/step from issue 14, edits)
SCENES = {
    "sample": ("sample as is (NSCH_FDM 32^3, 8 particles)", 95.2, {}),
    "ns32": ("Navier_Stokes 32^3, 1 particle (A 4)", 7.9,
             {"type": "Navier_Stokes", "np": 5, "n": 1, "A": 4.0}),
    "ns64": ("Navier_Stokes 64^3, 1 particle (A 4)", 53.3,
             {"type": "Navier_Stokes", "np": 6, "n": 1, "A": 4.0}),
    "ns64x100": ("Navier_Stokes 64^3, 100 particles (A 2)", 89.9,
                 {"type": "Navier_Stokes", "np": 6, "n": 100, "A": 2.0}),
    "fdm64e": ("Navier_Stokes_FDM explicit 64^3, 8 particles", 137.0,
               {"type": "Navier_Stokes_FDM", "np": 6, "solver": "explicit_scheme"}),
    "fdm64i": ("Navier_Stokes_FDM implicit 64^3, 8 particles", 334.0,
               {"type": "Navier_Stokes_FDM", "np": 6, "solver": "implicit_scheme"}),
    "nsch64": ("Navier_Stokes_Cahn_Hilliard_FDM 64^3, 8 particles", 882.0, {"np": 6}),
    "le32": ("Shear_Navier_Stokes_Lees_Edwards 32^3, 8 particles", 20.8,
             {"type": "Shear_Navier_Stokes_Lees_Edwards"}),
}


def make_input(directory: Path, edits: dict, num_snap: int) -> Path:
    """input.udf of a scene in ``directory`` (with define.udf), Num_snap snapshots of GTS 10."""
    for f in ("define.udf", "kapsel_unit.udf"):
        if (ROOT / "samples" / f).exists():
            shutil.copy(ROOT / "samples" / f, directory / f)
    u = UDFManager(str(ROOT / "samples" / "input.udf"))
    if "type" in edits:
        u.put(edits["type"], "constitutive_eq.type")
    typ = u.get("constitutive_eq.type")
    u.put(0.0, f"constitutive_eq.{typ}.kBT")
    if "solver" in edits:
        u.put(edits["solver"], f"constitutive_eq.{typ}.NS_solver.type")
    if "np" in edits:
        for ax in "XYZ":
            u.put(edits["np"], f"mesh.NP{ax}")
    if "n" in edits:
        u.put(edits["n"], "object_type.spherical_particle.Particle_spec[0].Particle_number")
    if "A" in edits:
        u.put(edits["A"], "A")
    u.put("auto", "time_increment.type")
    u.put(1.0, "time_increment.auto.factor")
    u.put(10, "output.GTS")
    u.put(num_snap, "output.Num_snap")
    path = directory / "input.udf"
    u.write(str(path))
    return path


_FIRST_STEP = """
import sys, time
import kapsel.simulation as S
run = S.run
def timed(cfg, args, doc, model, resumed=False):
    def first():
        print("%.3f" % time.process_time())
        sys.exit(0)
    model.advance = first
    return run(cfg, args, doc, model, resumed)
S.run = timed
import kapsel.cli
sys.argv = ["kapsel-py"] + sys.argv[1:]
kapsel.cli.main()
"""


def _env(compiled="1"):
    return dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
                OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1",
                KAPSEL_PY_COMPILED=compiled)


def first_step_cpu(directory: Path, threads: int) -> float:
    """CPU seconds from the start of the process to the first time step (imports, input,
    set-up, output files, the initial snapshot), with the default KAPSEL_PY_COMPILED=auto."""
    cmd = [sys.executable, "-c", _FIRST_STEP, "-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf",
           "-Rrestart.udf", "--overwrite", "--quiet", "--seed", "1", "--threads", str(threads)]
    out = subprocess.run(cmd, cwd=directory, env=_env("auto"), capture_output=True, text=True,
                         check=True).stdout
    return float(out.split()[-1])


def cpu_run(directory: Path, threads: int) -> tuple[float, float]:
    """(CPU seconds, peak RSS MB) of one kapsel-py run in ``directory`` (compiled kernels
    from the start, KAPSEL_PY_COMPILED=1, so that their loading cancels in the difference)."""
    env = _env("1")
    cmd = [sys.executable, "-m", "kapsel.cli", "-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf",
           "-Rrestart.udf", "--overwrite", "--quiet", "--seed", "1", "--threads", str(threads)]
    proc = subprocess.Popen(cmd, cwd=directory, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    _, status, ru = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode()
    proc.stderr.close()
    if proc.returncode != 0:
        raise RuntimeError(f"kapsel-py failed in {directory}: {err.strip()}")
    return ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024.0


def measure(name: str, threads: int, repeat: int, keep: Path | None):
    label, original, edits = SCENES[name]
    base = keep if keep is not None else Path(tempfile.mkdtemp(prefix=f"bench-{name}-"))
    cpu, rss = {}, 0.0
    for snaps in (2, 6):
        d = base / f"{name}-{snaps * 10}"
        d.mkdir(parents=True, exist_ok=True)
        make_input(d, edits, snaps)
        best = min(cpu_run(d, threads) for _ in range(repeat))
        cpu[snaps] = best[0]
        rss = max(rss, best[1])
    startup = min(first_step_cpu(base / f"{name}-20", threads) for _ in range(repeat))
    if keep is None:
        shutil.rmtree(base, ignore_errors=True)
    ms = (cpu[6] - cpu[2]) / 40 * 1e3
    env = _env("1")
    step = min(float(subprocess.run(
        [sys.executable, str(ROOT / "bench" / "profile_step.py"), name, "--steps", "40",
         "--time-only", "--threads", str(threads)], env=env, check=True, capture_output=True, text=True).stdout.split()[-1])
        for _ in range(repeat))
    return label, original, ms, startup, rss, step


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", nargs="*", choices=list(SCENES), default=list(SCENES))
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--keep", type=Path, help="keep the runs under this directory")
    a = ap.parse_args(argv)
    print(f"| scene (from samples/input.udf, kBT 0, auto dt, GTS 10) | original ms/step | "
          f"kapsel-py ms/step | ratio | step only ms | ratio | start-up s CPU | peak RSS MB |")
    print("|---|---|---|---|---|---|---|---|")
    for name in a.scene:
        label, original, ms, startup, rss, step = measure(name, a.threads, a.repeat, a.keep)
        print(f"| {label} | {original:.1f} | {ms:.1f} | {ms / original:.2f} | {step:.1f} | "
              f"{step / original:.2f} | {startup:.2f} | {rss:.0f} |", flush=True)


if __name__ == "__main__":
    main()
