"""The console of a run, as the original writes it (FORMAT-OUTPUT.md §1.3, §1.4, §1.6).

stderr, unless --quiet:
- at every snapshot after the first of the run, the original's line
  ``# Step: %9d/%9d\t  Block time (m): %8.3f\t Global time (m): %8.3f/%8.3f``
  (step, last step, wall minutes since the previous line, since the program started, and
  the estimate of the minutes left);
- between snapshots that are far apart, a heartbeat ``#step s/N  t=...  r steps/s  ETA``
  when no line was written for ``every`` seconds, the first one ``first`` seconds after the
  loop started (so a run whose first snapshot is far off says within seconds that it runs
  and how fast; the original's line already says step, total, elapsed and remaining time,
  so this only fills long snapshot intervals);
- at the end ``#<output> end.``, ``#<restart> end.``, ``#Simulation has ended!`` and the
  total running time and average step time in s, m and h.

The sheared types' stress table (ShearTable): the header on stdout at the start, a row
after every step (stdout for the Lees-Edwards types, stderr for Shear_Navier_Stokes).
"""
from __future__ import annotations

import sys
import time

#: when the program started (kapsel.cli sets it; the import time otherwise)
PROGRAM_START = time.perf_counter()


class Progress:
    """Snapshot lines, heartbeat and the closing summary on ``stream`` (stderr)."""

    def __init__(self, total_steps: int, quiet: bool = False, every: float = 60.0,
                 stream=None, gts: int = 1, start_step: int = 0, program_start=None,
                 first: float = 10.0):
        self.total = total_steps
        self.quiet = quiet
        self.every = every
        self.first = min(first, every)
        self.spoken = False      # a line written since the loop started
        self.stream = stream
        self.gts = max(1, int(gts))
        self.start_step = int(start_step)
        self.program_start = PROGRAM_START if program_start is None else program_start
        self.t0 = time.perf_counter()          # end of initialisation
        self.block_start = self.t0
        self.last = self.t0
        self.steps = 0

    def _out(self):
        return self.stream or sys.stderr

    def step(self, step: int, sim_time: float) -> None:
        self.steps += 1
        now = time.perf_counter()
        wait = self.every if self.spoken else self.first
        if self.quiet or now - self.last < wait:
            return
        self.last = now
        self.spoken = True
        rate = self.steps / (now - self.t0)
        left = (self.total - step) / rate if rate > 0 else float("inf")
        print(f"#step {step}/{self.total}  t={sim_time:.6g}  {rate:.2f} steps/s  "
              f"ETA {format_duration(left)}", file=self._out(), flush=True)

    def snapshot(self, step: int) -> str:
        """The original's line at a snapshot (§1.3); returned, printed unless quiet."""
        now = time.perf_counter()
        block = (now - self.block_start) / 60.0
        self.block_start = self.last = now
        self.spoken = True
        left = (self.total - step + 1) / self.gts * block
        line = (f"# Step: {step:9d}/{self.total:9d}\t  Block time (m): {block:8.3f}\t "
                f"Global time (m): {(now - self.program_start) / 60.0:8.3f}/{left:8.3f}")
        if not self.quiet:
            print(line, file=self._out(), flush=True)
        return line

    def summary(self, output: str | None = None, restart: str | None = None) -> str:
        """The original's closing lines (§1.6); returned, printed unless quiet."""
        total = time.perf_counter() - self.program_start
        avg = total / max(self.total - self.start_step + 1, 1)
        lines = []
        if output:
            lines.append(f"#{output} end.")
        if restart:
            lines.append(f"#{restart} end.")
        lines.append("#Simulation has ended!")
        for label, v in (("Total Running Time ", total), ("Average Step Time  ", avg)):
            lines.append(f"#{label}(s): {v:10.2f}")
            lines.append(f"#{'':{len(label)}}(m): {v / 60:10.2f}")
            lines.append(f"#{'':{len(label)}}(h): {v / 3600:10.2f}")
        text = "\n".join(lines)
        if not self.quiet:
            print(text, file=self._out(), flush=True)
        return text


class ShearTable:
    """The sheared types' stress table (§1.4): ``#1:time 2:... `` then ``%16.8g`` rows."""

    def __init__(self, labels, rows_to: str = "stdout", quiet: bool = False):
        self.labels = tuple(labels)
        self.rows_to = rows_to
        self.quiet = quiet

    def header(self) -> str:
        return "#" + "".join(f"{i + 1}:{name} " for i, name in enumerate(self.labels))

    def print_header(self) -> None:
        print(self.header(), file=sys.stdout, flush=True)

    @staticmethod
    def format_row(values) -> str:
        return " ".join(f"{float(v):16.8g}" for v in values)

    def row(self, values) -> None:
        if self.rows_to == "stderr":
            if not self.quiet:
                sys.stderr.write(self.format_row(values) + "\n")
        else:
            sys.stdout.write(self.format_row(values) + "\n")


def format_duration(seconds: float) -> str:
    if seconds == float("inf"):
        return "?"
    s = int(seconds)
    return f"{s // 3600}h{s % 3600 // 60:02d}m{s % 60:02d}s" if s >= 3600 else \
        f"{s // 60}m{s % 60:02d}s"
