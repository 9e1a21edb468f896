"""What a run shows while it goes: :class:`RunProgress`, the progress observer of ``uwcosim run``
and ``uwcosim demo`` (passed as ``simulate(progress=...)``).

On a terminal: a tqdm bar on stderr (simulated time, steps per second, time remaining), as
``uwcosim campaign`` shows one for its runs and OMSimulator for ``stepUntil``. Otherwise (a
pipe, a log file, CI): one line per stage on stderr: compiling kernels (first use only),
simulating, evaluating, figures; no bar characters in a log. :meth:`RunProgress.compiling` is
the hook of :data:`uwcosim.core.jit.on_compile`: the first kernel Numba compiles (a kernel not
in its on-disk cache) makes it say what it is doing and how long that usually takes.

A replay of recorded data (``[replay]``) has no step count in its scenario: the bar takes its
total from the replay's view at the first row (``view.total``,
:class:`uwcosim.run.replay.ReplayTotal`: the steps after the first row, the first and last
time stamps, the file), shows the rows' own time stamps (they may be irregular) and ends, like a
simulation, with the time the replay took and the evaluation stage.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

#: what the first compile of the filters' kernels costs on a 2-core machine (measured: 1 min
#: 24 s for the six filters of tan_terrain, 2 min 45 s with every filter of the campaigns)
COMPILE_NOTE = ("compiling the filters' Numba kernels (first use after an install or an "
                "update: usually 1-3 min on 2 cores, once; later runs load them from the cache "
                "in under a second)")


class RunProgress:
    """Observer of a run's steps (``on_step(k, view)``) that shows its progress on ``stream``.

    ``steps``: the number of steps (None when unknown: a replay's is read from the view at
    ``k = 0``, module docstring); ``step_s``, ``t0``: the time grid; ``bar``: a tqdm bar
    (default: when ``stream`` is a terminal); ``enabled`` False shows nothing (``-q``)."""

    def __init__(self, steps: int | None, step_s: float | None = None, t0: float = 0.0,
                 stream: TextIO | None = None, bar: bool | None = None,
                 enabled: bool = True) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.steps = steps
        self.step_s = step_s
        self.t0 = t0
        self.enabled = enabled
        isatty = getattr(self.stream, "isatty", None)
        self.use_bar = enabled and (bar if bar is not None else bool(isatty and isatty()))
        self._bar = None
        self._t_start: float | None = None
        self._compile_t: float | None = None
        self._compiled = 0
        self._verb = "simulat"  # simulating / simulated; "replay" for a replay
        self.lines: list[str] = []  # what was said (the tests read it)

    # -- stages ---------------------------------------------------------------------------------

    def stage(self, text: str) -> None:
        """One line ``uwcosim: TEXT`` on the stream (above the bar, if one is shown)."""
        self.lines.append(text)
        if not self.enabled:
            return
        line = f"uwcosim: {text}"
        if self._bar is not None:
            self._bar.write(line, file=self.stream)
        else:
            print(line, file=self.stream, flush=True)

    def compiling(self, kernel: str) -> None:
        """:data:`uwcosim.core.jit.on_compile`: Numba compiles ``kernel`` (a cache miss)."""
        self._compiled += 1
        if self._compile_t is None:
            self._compile_t = time.perf_counter()
            self.stage(COMPILE_NOTE)

    # -- the observer ---------------------------------------------------------------------------

    def on_step(self, k: int, view) -> None:
        if k == 0:
            self._begin(getattr(view, "total", None))
            return
        if self._bar is not None and (k & 15 == 0 or k == self.steps):
            self._bar.n = k
            if self.step_s is not None:
                self._bar.set_postfix_str(f"t = {self.t0 + k * self.step_s:g} s", refresh=False)
            elif self._verb == "replay":  # the row's own time stamp
                self._bar.set_postfix_str(f"t = {view.t:g} s", refresh=False)
            self._bar.refresh() if k == self.steps else self._bar.update(0)
        if self.steps is not None and k == self.steps:
            self.end()

    def _begin(self, total=None) -> None:
        """The first row: ``total`` a replay's :class:`~uwcosim.run.replay.ReplayTotal`
        (None for a simulation)."""
        self._t_start = time.perf_counter()
        if total is not None and self.steps is None:  # a replay: its total from the file
            self.steps, self.step_s, self.t0 = int(total.steps), None, float(total.t_first)
            self._verb = "replay"
            what = (f"replaying {total.steps} steps ({total.steps + 1} rows of {total.file}, "
                    f"t = {total.t_first:g} .. {total.t_last:g} s)")
        elif self.steps is not None and self.step_s is not None:
            t1 = self.t0 + self.steps * self.step_s
            what = (f"simulating {self.steps} steps of {self.step_s:g} s "
                    f"(t = {self.t0:g} .. {t1:g} s)")
        else:
            what = "simulating"
        if self.use_bar:
            from tqdm import tqdm

            self.lines.append(what)
            # smoothing 0: the rate and the time remaining are the run's average so far
            self._bar = tqdm(total=self.steps, unit="step", file=self.stream, smoothing=0,
                             dynamic_ncols=True, desc=f"{self._verb}ing", leave=False,
                             mininterval=0.2)
        else:
            self.stage(what)

    def end(self) -> None:
        """The last step: close the bar, say how long it took and that evaluation follows."""
        if self._t_start is None:
            return
        wall = time.perf_counter() - self._t_start
        self._t_start = None
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        done = f"{self._verb}ed {self.steps} steps in {wall:.1f} s" if self.steps else \
            f"{self._verb}ed in {wall:.1f} s"
        if self.steps and wall > 0:
            done += f" ({self.steps / wall:,.0f} steps/s)"
        if self._compile_t is not None:
            done += f", of which compiling {self._compiled} kernels on first use"
        self.stage(done)
        self.stage("evaluating (summary.json)")

    def close(self) -> None:
        """End a run that stopped before its last step (the bar is removed)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None
