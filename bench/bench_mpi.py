"""Strong scaling of distributed runs (docs/distributed.md).

    .venv/bin/python bench/bench_mpi.py [--sizes 64 128] [--ranks 1 2] [--particles 20]
                                        [--steps 10] [--types Navier_Stokes ...]
                                        [--ns explicit_scheme] [--ch implicit_scheme]

For each type and mesh N^3: the plain (serial, no MPI) run and ``mpiexec -n P`` for each P,
on the manual's sample input (samples/input.udf) turned into that type (default
Navier_Stokes; the FDM types with the MAC scheme ``--ns`` and the Cahn-Hilliard scheme
``--ch``, default the sample's) with N^3 cells, ``--particles`` particles (A = 4) and no
thermal noise.  For the FDM types the last column adds the wall time per step the halo
exchanges took (kapsel.mesh.halo: copies into the padded blocks and MPI_Sendrecv, the
slowest rank).  Each run builds the model as
``kapsel-py`` does (kapsel.cli.prepare: input, model, particles, FFT plans), makes 2
warm-up steps, then times ``--steps`` steps between two barriers (rank 0's wall clock):
the time per step of the time loop, without start-up or output (and the CPU time per step
of the slowest rank: MPICH polls while it waits, so this counts waiting too, but not the
time the rank was kept off a busy machine's cores).  The fastest of ``--repeat`` runs is
kept.  Efficiency E = T_serial / (P T_P).
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



def sample_input(d, eq, n):
    """The manual's sample in ``d`` as ``eq`` on an n^3 mesh (n a power of 2): the tests'
    tests/builders.py sample_input, a UDFManager the caller finishes and writes."""
    sys.path.insert(0, os.path.join(ROOT, "tests"))
    from builders import sample_input as sample
    return sample(d, eq, npx=n.bit_length() - 1)            # N = 2^NP


def make_input(d, n, particles, eq="Navier_Stokes", ns=None, ch=None):
    u = sample_input(d, eq, n)
    u.put(0.0, f"constitutive_eq.{eq}.kBT")
    if ns is not None and eq != "Navier_Stokes":
        u.put(ns, f"constitutive_eq.{eq}.NS_solver.type")
    if ch is not None and eq == "Navier_Stokes_Cahn_Hilliard_FDM":
        u.put(ch, f"constitutive_eq.{eq}.CH_solver.type")
    u.put(particles, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put("OFF", "output.AVS")
    u.write(os.path.join(d, "input.udf"))


def prepared_model():
    """(model, MPI communicator or None) of the input in the working directory, built as
    ``kapsel-py`` builds it (under mpiexec or not), BLAS on one thread as kapsel-py runs."""
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")     # as kapsel-py does (kapsel.cli.single_threaded_blas)
    from kapsel.cli import build_parser, prepare
    from kapsel.parallel import start
    args = build_parser().parse_args(["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf",
                                      "-Rrestart.udf", "--seed", "1", "--quiet", "--overwrite"])
    args.dist = start(args)
    prepared = prepare(args)
    if isinstance(prepared, int):
        raise SystemExit(prepared)
    return prepared[2], (args.dist.comm if args.dist.size > 1 else None)


def worker(steps):
    """In the run directory (under mpiexec or not): build the model, time ``steps`` steps."""
    model, comm = prepared_model()
    for _ in range(2):
        model.advance()
    if comm is not None:
        comm.Barrier()
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        model.advance()
    c = (time.process_time() - c0) / steps
    if comm is not None:
        comm.Barrier()
        c = comm.allreduce(c, op=_max())
    t = (time.perf_counter() - t0) / steps
    halos = [getattr(x, "halo", None) for x in (getattr(model, "mac", None),
                                                getattr(model, "ch", None))]
    h = sum(x.seconds for x in halos if x is not None) / (steps + 2)
    if comm is not None:
        h = comm.allreduce(h, op=_max())
    if comm is None or comm.Get_rank() == 0:
        sys.__stdout__.write(f"{h:.6f} {t:.6f} {c:.6f}\n")


def _max():
    from mpi4py import MPI
    return MPI.MAX


def launch(script, d, ranks, steps, env=None):
    """The words ``script --worker steps`` prints, run in ``d`` (under the venv's mpiexec
    -n ``ranks`` when ``ranks``, else plainly)."""
    cmd = [sys.executable, os.path.abspath(script), "--worker", str(steps)]
    if ranks:
        mpiexec = (shutil.which("mpiexec", path=os.path.dirname(sys.executable))
                   or shutil.which("mpiexec"))
        cmd = [mpiexec, "-n", str(ranks)] + cmd
    r = subprocess.run(cmd, cwd=d, capture_output=True, text=True, env=env)
    if r.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed in {d}:\n{r.stderr[-2000:]}")
    return r.stdout.split()


def timed(d, ranks, steps):
    h, t, c = (float(x) for x in launch(__file__, d, ranks, steps)[-3:])
    return t, c, h


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 128])
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--particles", type=int, default=20)
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--types", nargs="+", default=["Navier_Stokes"])
    ap.add_argument("--ns", default=None, help="NS_solver of the FDM types")
    ap.add_argument("--ch", default=None, help="CH_solver of Navier_Stokes_Cahn_Hilliard_FDM")
    ap.add_argument("--worker", type=int, default=None, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker is not None:
        return worker(a.worker)
    if any(n & (n - 1) for n in a.sizes):
        raise SystemExit("--sizes: powers of two (the input gives 2^NP)")
    print(f"{a.particles} particles, {a.steps} timed steps, best of {a.repeat}\n"
          f"| type | mesh | run | ms / step | speed-up | efficiency | CPU ms / step "
          f"(slowest rank) | halo ms / step |\n|---|---|---|---|---|---|---|---|",
          flush=True)
    with tempfile.TemporaryDirectory(prefix="bench_mpi-") as tmp:
        for eq in a.types:
            name = eq + (f" ({a.ns}" + (f", CH {a.ch}" if a.ch and "Cahn" in eq else "") + ")"
                         if a.ns and eq != "Navier_Stokes" else "")
            for n in a.sizes:
                d = os.path.join(tmp, f"{eq}-n{n}")
                make_input(d, n, a.particles, eq, a.ns, a.ch)
                t0, c0, _ = min(timed(d, 0, a.steps) for _ in range(a.repeat))
                print(f"| {name} | {n}^3 | serial (no MPI) | {1e3 * t0:.1f} | 1 | 1 | "
                      f"{1e3 * c0:.1f} | |", flush=True)
                for p in a.ranks:
                    t, c, h = min(timed(d, p, a.steps) for _ in range(a.repeat))
                    hs = f"{1e3 * h:.1f}" if eq != "Navier_Stokes" else ""
                    print(f"| {name} | {n}^3 | mpiexec -n {p} | {1e3 * t:.1f} | {t0 / t:.2f} | "
                          f"{t0 / (p * t):.2f} | {1e3 * c:.1f} | {hs} |", flush=True)


if __name__ == "__main__":
    main()
