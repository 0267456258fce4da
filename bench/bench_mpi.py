"""Strong scaling of distributed Navier_Stokes runs (README "Distributed runs").

    .venv/bin/python bench/bench_mpi.py [--sizes 64 128] [--ranks 1 2] [--particles 20]

For each mesh N^3: the plain (serial, no MPI) run and ``mpiexec -n P kapsel-py`` for each P,
on the manual's sample input (samples/input.udf) turned into Navier_Stokes with N^3 cells,
``--particles`` particles and no thermal noise.  Time per step = (wall time of a run of S2
steps - that of S1 steps) / (S2 - S1), which removes the start-up (imports, FFTW plans,
reading the input) from the comparison; each run is repeated and the fastest kept.
Efficiency E = T_serial / (P T_P).  The runs write into a temporary directory.
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..")
sys.path.insert(0, ROOT)
from udf import UDFManager  # noqa: E402

SAMPLES = os.path.join(ROOT, "samples")


def make_input(d, n, particles, steps):
    os.makedirs(d, exist_ok=True)
    for f in ("define.udf", "kapsel_unit.udf"):
        shutil.copy(os.path.join(SAMPLES, f), os.path.join(d, f))
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u.put("Navier_Stokes", "constitutive_eq.type")
    for k in ("NPX", "NPY", "NPZ"):
        u.put(n.bit_length() - 1, f"mesh.{k}")            # N = 2^NP
    u.put(0.0, "constitutive_eq.Navier_Stokes.kBT")
    u.put(particles, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put(steps, "output.GTS")
    u.put(1, "output.Num_snap")
    u.put("OFF", "output.AVS")
    u.write(os.path.join(d, "input.udf"))


def mpiexec():
    return (shutil.which("mpiexec", path=os.path.dirname(sys.executable))
            or shutil.which("mpiexec"))


def wall(d, ranks):
    cmd = [sys.executable, "-m", "kapsel.cli", "-Iinput.udf", "-Ooutput.udf",
           "-Ddefine.udf", "-Rrestart.udf", "--seed", "1", "--quiet", "--overwrite"]
    if ranks:
        cmd = [mpiexec(), "-n", str(ranks)] + cmd
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    t0 = time.perf_counter()
    r = subprocess.run(cmd, cwd=d, capture_output=True, text=True, env=env)
    t = time.perf_counter() - t0
    if r.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed in {d}:\n{r.stderr[-2000:]}")
    return t


def per_step(tmp, n, particles, ranks, s1, s2, repeat):
    best = {}
    for s in (s1, s2):
        d = os.path.join(tmp, f"n{n}_p{ranks}_s{s}")
        make_input(d, n, particles, s)
        best[s] = min(wall(d, ranks) for _ in range(repeat))
    return (best[s2] - best[s1]) / (s2 - s1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 128])
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--particles", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=2)
    a = ap.parse_args()
    if any(n & (n - 1) for n in a.sizes):
        raise SystemExit("--sizes: powers of two (the input gives 2^NP)")
    steps = {64: (4, 24), 128: (2, 10)}
    print(f"| mesh | run | s / step | speed-up | efficiency |\n|---|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="bench_mpi-") as tmp:
        for n in a.sizes:
            s1, s2 = steps.get(n, (2, 10))
            t0 = per_step(tmp, n, a.particles, 0, s1, s2, a.repeat)
            print(f"| {n}^3 | serial (no MPI) | {t0:.3f} | 1 | 1 |", flush=True)
            for p in a.ranks:
                t = per_step(tmp, n, a.particles, p, s1, s2, a.repeat)
                print(f"| {n}^3 | mpiexec -n {p} | {t:.3f} | {t0 / t:.2f} | "
                      f"{t0 / (p * t):.2f} |", flush=True)


if __name__ == "__main__":
    main()
