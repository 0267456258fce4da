"""The exceptions a run ends with (the bottom of the package: imports nothing of kapsel)."""
from __future__ import annotations

__all__ = ["InstabilityError", "RunError", "Interrupted", "NothingToDo", "SolverDidNotConverge",
           "UnstableTimeStep"]


class InstabilityError(Exception):
    """NaN or infinity in the fields or particles."""


class RunError(Exception):
    """The run stopped before its end (an instability, a solver that did not converge, a
    file that cannot be written, no memory): ``str(e)`` is the message the command line
    prints after ``kapsel-py: error: ``; the restart holds the last good state."""

    prefix = "error: "

    @property
    def line(self) -> str:
        """The line the command line prints."""
        return f"kapsel-py: {self.prefix}{self}"


class Interrupted(RunError):
    """SIGINT or SIGTERM: the run stopped at the end of a step, its state saved."""

    prefix = ""


class NothingToDo(Exception):
    """The input is the restart of a run that has reached its last step."""


class SolverDidNotConverge(RuntimeError):
    """BiCGSTAB did not reach ``tolerance`` within ``maximum_iteration`` (manual table 2)."""

    def __init__(self, iterations, residual, message=None, what="BiCGSTAB"):
        self.iterations = int(iterations)
        self.residual = float(residual)
        super().__init__(message or (
            "%s did not converge in %d iterations: relative residual %.3e; reduce the time "
            "step or raise maximum_iteration" % (what, self.iterations, self.residual)))


class UnstableTimeStep(ValueError):
    """dt above an explicit scheme's stability limit."""
