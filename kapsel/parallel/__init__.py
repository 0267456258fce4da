"""Distributed runs over MPI (docs/distributed.md).

``start(args)`` is called by the command line before anything else: it returns the run's
world, a ``OneRank`` for a plain run (its collectives are identities; mpi4py is then never
imported) or a ``Dist`` when the process was started by an MPI launcher (mpiexec / mpirun /
srun: their PMI or Open MPI environment variables) or was given the original's ``-X`` /
``-Y`` process-grid flags with X Y > 1.  A plain run is the one-rank case of the protocol:
the same calls, answered at once.

Which types run distributed: ``DISTRIBUTED``.  Any other type is refused with more than one
rank (``refuse``), never run serially on every rank writing the same files.

Division of work (kapsel.mesh.pencil for the fields, kapsel.particles.ownership for the
particles, kapsel.parallel.lockstep for the output): every rank holds its block of the
fields.  Spheres and chain beads are owned by the rank whose block holds their stencil's
base point, rigid bodies (whole, with all their beads) by the owner of their first bead's
base point; a rank holds its owned particles and ghosts (copies of the particles owned
elsewhere that its block needs: their profile meets it, or they are within the reach of
the forces of its particles), couples them to its part of the fluid, sends the ghosts'
partial coupling sums to their owners (added in rank order: bit-for-bit repeatable), moves
its owned particles and exchanges them afterwards (migration and new halos)
(kapsel.particles.spm ``_step_owned``).  Dipoles (and Quincke rollers) are owned alike,
their Ewald sum distributed (kapsel.particles.ewald ``dipolar_ewald_owned``: the real-space
part over owned + ghosts, the halo widened to its cutoff; the structure sums of the owned
particles summed over the ranks by MPI_Reduce to rank 0 + MPI_Bcast).  Self-propelled
particles are owned too (kapsel.particles.janus ``update_velocities``).
Rank 0 writes output.udf, restart.udf and the field files with the fields and
the particle table gathered to it.  Limits: docs/distributed.md.
"""
from __future__ import annotations

import os
import sys

__all__ = ["DISTRIBUTED", "Dist", "OneRank", "launched_size", "make_layout", "start", "world"]

from ..typespec import names

DISTRIBUTED = names(distributed=True)       # kapsel.typespec

_SIZE_VARS = ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE", "MV2_COMM_WORLD_SIZE", "PMIX_SIZE")


def launched_size() -> int | None:
    """Number of ranks an MPI launcher started this process with, None if none did."""
    for v in _SIZE_VARS:
        s = os.environ.get(v)
        if s and s.isdigit():
            return int(s)
    return None


class DistError(Exception):
    """A distributed run cannot start (message for the user)."""


class Dist:
    """The MPI world of a run: ``comm``, ``rank``, ``size``, process grid ``dims`` (px, py)."""

    def __init__(self, comm, dims):
        self.comm = comm
        self.rank = comm.Get_rank()
        self.size = comm.Get_size()
        self.dims = dims
        self.lockstep = None        # kapsel.parallel.lockstep.Lockstep, set by the model

    @property
    def root(self) -> bool:
        return self.rank == 0

    def agree(self, status):
        """The worst of every rank's ``status`` (None = fine, else an exit code), on every
        rank: a refusal on one rank stops them all, before any collective work."""
        code = 0 if status is None else int(status)
        return self.allmax(code) or None

    def bcast(self, value):
        return self.comm.bcast(value, root=0)

    def allmax(self, value):
        """The largest of every rank's ``value``, on every rank."""
        return self.comm.allreduce(value, op=_mpi().MAX)

    def layout(self, shape, dx, threads=1):
        """This rank's blocks of the mesh (kapsel.mesh.pencil.PencilGrid)."""
        from ..mesh.pencil import PencilGrid
        return PencilGrid(shape, dx, self.comm, self.dims)

    def describe(self) -> list[str]:
        """The banner's line on the division of work."""
        return [f"distributed over {self.size} MPI rank(s), process grid -X{self.dims[0]} "
                f"-Y{self.dims[1]} (fields split along x and y); rank 0 writes the files"]

    def __repr__(self):
        return f"Dist(rank {self.rank} of {self.size}, grid {self.dims[0]} x {self.dims[1]})"


class _SelfComm:
    """The communicator of a one-rank world: every collective returns its own value."""

    def Get_rank(self):
        return 0

    def Get_size(self):
        return 1

    def bcast(self, value, root=0):
        return value

    def allreduce(self, value, op=None):
        return value


class OneRank(Dist):
    """The world of a plain run: rank 0 of 1, process grid 1 x 1, collectives answered at
    once, the whole mesh (kapsel.mesh.grid.Grid) as its layout; mpi4py is never imported."""

    def __init__(self):
        super().__init__(_SelfComm(), (1, 1))

    def allmax(self, value):
        return value

    def layout(self, shape, dx, threads=1):
        from ..mesh.grid import Grid
        return Grid(shape, dx, threads=threads)

    def describe(self) -> list[str]:
        return []

    def __repr__(self):
        return "OneRank()"


def world(args):
    """The run's world: ``args.dist`` (set by ``start``), a ``OneRank`` when unset (a model
    built without the command line: kapsel.api, tests)."""
    return getattr(args, "dist", None) or OneRank()


def _mpi():
    from mpi4py import MPI
    return MPI


def start(args):
    """The run's world (module docstring): a ``OneRank`` for a plain run, else the ``Dist``
    of this process.  Raises
    DistError when mpi4py is missing or the -X / -Y grid does not match the ranks."""
    X, Y = getattr(args, "X", None), getattr(args, "Y", None)
    launched = launched_size()
    for flag, v in (("-X", X), ("-Y", Y)):
        if v is not None and v < 1:
            raise DistError(f"{flag} must be at least 1, got {v}")
    grid = (X or 1) * (Y or 1)
    if launched is None and grid == 1:
        return OneRank()
    try:
        from mpi4py import MPI
    except ImportError:
        raise DistError("a distributed run needs mpi4py and an MPI library: pip install "
                        "'kapsel-py[mpi]' (the mpi4py and mpich wheels)") from None
    comm = MPI.COMM_WORLD
    size = comm.Get_size()
    if launched is not None and launched != size:
        raise DistError(f"started by an MPI launcher for {launched} ranks, but the MPI library "
                        f"of mpi4py sees {size}: the mpirun / mpiexec is not that of the MPI "
                        f"library mpi4py uses (use the one installed with it, e.g. the venv's "
                        f"bin/mpiexec of the mpich wheel); every process would otherwise run "
                        f"the whole input alone")
    if X is None and Y is None:
        dims = (size, 1)
    elif X is None:
        dims = (size // Y, Y)
    elif Y is None:
        dims = (X, size // X)
    else:
        dims = (X, Y)
    if dims[0] * dims[1] != size:
        raise DistError(f"the process grid -X{X or '?'} -Y{Y or '?'} does not match the "
                        f"{size} rank(s) of this run (X Y must equal the number of ranks; "
                        f"start with mpirun -n {(X or 1) * (Y or 1)})")
    dist = Dist(comm, dims)
    if not dist.root:                         # one voice: rank 0 speaks for the run
        sys.stdout = open(os.devnull, "w")
        sys.stderr = open(os.devnull, "w")
        hook = sys.excepthook

        def abort(*exc):                      # a failure on one rank ends them all
            sys.stderr = sys.__stderr__
            hook(*exc)
            comm.Abort(1)
        sys.excepthook = abort
    return dist


def make_layout(shape, dx, dist, threads=1):
    """The layout of a run's mesh in ``dist``, the run's world: a ``kapsel.mesh.grid.Grid`` on
    one process, else this rank's blocks of it (kapsel.mesh.pencil.PencilGrid on the
    world's process grid; ValueError when the mesh is too small for it)."""
    return dist.layout(shape, dx, threads)


def refuse(dist, cfg) -> str | None:
    """Why the run of ``cfg`` cannot be distributed over ``dist`` (None: it can; one rank
    always can: a run that cannot be distributed then runs as a plain run)."""
    if dist.size == 1:
        return None
    return not_distributed(cfg)


def not_distributed(cfg) -> str | None:
    """Why the run of ``cfg`` does not run distributed (None: it does)."""
    if cfg.type not in DISTRIBUTED:
        return (f"constitutive_eq.type {cfg.type} does not run distributed: run it on one "
                f"process (without mpirun, or mpirun -n 1); distributed types: "
                f"{', '.join(DISTRIBUTED)}")
    if getattr(cfg.switches, "wall", None) is not None:
        return ("switch.wall (flat walls) does not run distributed: run this input on one "
                "process (without mpirun, or mpirun -n 1)")
    return None
