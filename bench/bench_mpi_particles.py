"""Per-rank particle cost of a distributed Navier_Stokes run: particles owned by ranks (this
tree) against the replicated particle state (another tree, e.g. main before issue 18's
particle point) (docs/distributed.md).

    .venv/bin/python bench/bench_mpi_particles.py [--n 64] [--particles 2000] [--ranks 2]
        [--steps 10] [--tree /path/to/other/tree ...]

The input: the manual's sample as Navier_Stokes on n^3 cells, ``--particles`` spheres of
A = 2, XI = 1 placed at random, WCA pairs (LJ_truncate ON), thermal noise (kBT = 0.5).  Each
run builds the model as kapsel-py does (kapsel.cli.prepare), makes 2 warm-up steps, then
times ``--steps`` steps: the wall time per step (rank 0, between barriers) and its particle
part, the step minus the fluid's own work (SPM._fluid_step: the fluid step and the u*
transform; SPM._add_solenoidal: the projection of the increment), which both designs share
(the slowest rank's).  Memory: the peak resident set of each rank (ru_maxrss, the largest
printed) and the particle rows a rank holds (N replicated; owned + ghosts).
"""
import argparse
import os
import resource
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))


def make_input(d, n, particles):
    sys.path.insert(0, HERE)
    from bench_mpi import sample_input
    u = sample_input(d, "Navier_Stokes", n)
    u.put(0.5, "constitutive_eq.Navier_Stokes.kBT")
    u.put(2.0, "A")
    u.put(1.0, "A_XI")
    u.put("ON", "switch.LJ_truncate")
    u.put(particles, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put("OFF", "output.AVS")
    u.write(os.path.join(d, "input.udf"))


def worker(steps):
    import bench_mpi                           # (this directory is on sys.path)
    model, comm = bench_mpi.prepared_model()
    spm = model.spm
    spent = [0.0]

    def timed(fn):
        def run(*a, **k):
            t = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                spent[0] += time.perf_counter() - t
        return run
    spm._fluid_step = timed(spm._fluid_step)
    spm._add_solenoidal = timed(spm._add_solenoidal)
    for _ in range(2):
        model.advance()
    comm.Barrier()
    spent[0] = 0.0
    t0 = time.perf_counter()
    for _ in range(steps):
        model.advance()
    t_own = time.perf_counter() - t0
    part = (t_own - spent[0]) / steps
    comm.Barrier()
    t = (time.perf_counter() - t0) / steps
    part = comm.allreduce(part, op=bench_mpi._max())
    rss = comm.gather(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, root=0)
    rows = comm.gather(int(spm.p.n), root=0)
    if comm.Get_rank() == 0:
        sys.__stdout__.write(f"{t:.6f} {part:.6f} {max(rss):.1f} {max(rows)}\n")


def run(d, tree, ranks, steps):
    sys.path.insert(0, HERE)
    from bench_mpi import launch
    t, part, rss, rows = launch(__file__, d, ranks, steps,
                                env=dict(os.environ, PYTHONPATH=tree))[-4:]
    return float(t), float(part), float(rss), int(rows)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--particles", type=int, default=2000)
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--tree", nargs="*", default=[], help="other trees to compare")
    ap.add_argument("--worker", type=int, default=None, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker is not None:
        return worker(a.worker)
    print(f"{a.n}^3, {a.particles} particles (A = 2, XI = 1, WCA, noise), {a.ranks} ranks, "
          f"{a.steps} timed steps, best of {a.repeat}\n"
          f"| code | ms / step | particle part ms / step | peak RSS / rank MB | "
          f"particle rows / rank |\n|---|---|---|---|---|", flush=True)
    with tempfile.TemporaryDirectory(prefix="bench_mpi_particles-") as tmp:
        d = os.path.join(tmp, "run")
        make_input(d, a.n, a.particles)
        for tree in [ROOT] + a.tree:
            best = min((run(d, tree, a.ranks, a.steps) for _ in range(a.repeat)),
                       key=lambda x: x[1])
            t, part, rss, rows = best
            print(f"| {tree} | {1e3 * t:.1f} | {1e3 * part:.1f} | {rss:.0f} | {rows} |",
                  flush=True)


if __name__ == "__main__":
    main()
