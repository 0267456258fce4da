"""Rank 0 writes, every rank computes: the output protocol of a distributed run.

The writers (output.udf, restart.udf, field files) run on rank 0 only and ask for what they
need lazily (kapsel.snapshot).  Whatever they ask that needs the other ranks (a gathered
field, the kinetic energy, the gathered u_hat of the restart) is a *collective*: rank 0
broadcasts its name and arguments, then every rank runs it.  The other ranks meanwhile
``serve``: they wait for the next name until rank 0 says the output is done (or failed, in
which case they raise the same kind of error and end the run as rank 0 does).

    with lockstep.lead():        # rank 0           lockstep.serve()   # the other ranks
        ... writers ...
        lockstep.call("gather_u_hat")   <-broadcast->   runs "gather_u_hat"

Outside ``lead`` (the time loop, where every rank runs the same code) ``call`` runs the
collective directly on every rank.
"""
from __future__ import annotations

from contextlib import contextmanager

__all__ = ["Lockstep"]


class Lockstep:
    def __init__(self, dist):
        self.dist = dist
        self.ops = {}
        self.leading = False

    def register(self, name, fn):
        """``fn(*args)`` runs on every rank when rank 0 ``call``s ``name``."""
        self.ops[name] = fn

    def call(self, name, *args):
        if self.leading:
            self.dist.comm.bcast(("call", name, args), root=0)
        return self.ops[name](*args)

    @contextmanager
    def lead(self):
        """Rank 0's side of a round of output (context manager)."""
        self.leading = True
        try:
            yield
        except BaseException as e:
            self.leading = False
            self.dist.comm.bcast(("error", type(e).__name__, str(e)), root=0)
            raise
        self.leading = False
        self.dist.comm.bcast(("done",), root=0)

    def serve(self):
        """The other ranks' side: run rank 0's collectives until it is done."""
        while True:
            msg = self.dist.comm.bcast(None, root=0)
            if msg[0] == "call":
                self.ops[msg[1]](*msg[2])
            elif msg[0] == "done":
                return
            else:
                raise _error(msg[1], msg[2])

    def round(self, body):
        """Run ``body`` on rank 0 as one round of output, the others serving."""
        if self.dist.root:
            with self.lead():
                return body()
        self.serve()
        return None


def _error(kind, message):
    from ..errors import InstabilityError
    from ..errors import SolverDidNotConverge
    for cls in (InstabilityError, SolverDidNotConverge, FloatingPointError, OSError,
                KeyboardInterrupt):
        if cls.__name__ == kind:
            return cls(message)
    return RuntimeError(f"rank 0 failed: {kind}: {message}")
