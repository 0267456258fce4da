"""Progress on stderr for long runs, and the original's closing summary."""
from __future__ import annotations

import sys
import time


class Progress:
    """Prints step, time, steps per second and ETA at most every ``every`` seconds."""

    def __init__(self, total_steps: int, quiet: bool = False, every: float = 5.0,
                 stream=None):
        self.total = total_steps
        self.quiet = quiet
        self.every = every
        self.stream = stream or sys.stderr
        self.t0 = time.perf_counter()
        self.last = self.t0
        self.steps = 0

    def step(self, step: int, sim_time: float) -> None:
        self.steps += 1
        now = time.perf_counter()
        if self.quiet or now - self.last < self.every:
            return
        self.last = now
        rate = self.steps / (now - self.t0)
        left = (self.total - step) / rate if rate > 0 else float("inf")
        print(f"#step {step}/{self.total}  t={sim_time:.6g}  {rate:.2f} steps/s  "
              f"ETA {format_duration(left)}", file=self.stream, flush=True)

    def summary(self, stream=None) -> str:
        """The original's closing lines: total running time and average step time."""
        total = time.perf_counter() - self.t0
        avg = total / max(self.steps, 1)
        lines = ["#Simulation has ended!"]
        for label, v in (("Total Running Time", total), ("Average Step Time", avg)):
            lines.append(f"#{label} (s): {v:10.2f}")
            lines.append(f"#{'':{len(label) + 6}}(m): {v / 60:10.2f}")
            lines.append(f"#{'':{len(label) + 6}}(h): {v / 3600:10.2f}")
        text = "\n".join(lines)
        if not self.quiet:
            print(text, file=stream or sys.stdout, flush=True)
        return text


def format_duration(seconds: float) -> str:
    if seconds == float("inf"):
        return "?"
    s = int(seconds)
    return f"{s // 3600}h{s % 3600 // 60:02d}m{s % 60:02d}s" if s >= 3600 else \
        f"{s // 60}m{s % 60:02d}s"
