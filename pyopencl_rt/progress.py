"""The one-line progress bar of ``pyopencl-rt render`` (on stderr), with per-device rows."""
from __future__ import annotations

import click
import sys


class Progress:
    """A one-line progress bar on stderr: passes, elapsed, ETA, samples/s."""

    def __init__(self, total_passes, time_limit, n_pixels, quiet):
        self.total, self.time_limit, self.n_pixels, self.quiet = total_passes, time_limit, n_pixels, quiet
        self.last = 0.0
        self.tty = sys.stderr.isatty()
        self.base = 0  # passes already in the film (a resumed render); set by render_full
        self.rows = None  # per-device rows of a multi-device or Dask render
        self.shown = None
        self.samples = None  # samples so far, where passes x pixels would be wrong (adaptive sampling)

    def device_rows(self, rows):
        """Each device's (or Dask worker's) samples/s and share of the passes, as LuxCore shows them."""
        self.rows = rows

    def __call__(self, passes, elapsed):
        if self.samples is None:
            rate, passes = (passes * self.n_pixels / elapsed if elapsed > 0 else 0.0), passes + self.base
        else:  # adaptive: the samples taken and the mean spp (what --spp sets), not passes x pixels
            rate, passes = (self.samples / elapsed if elapsed > 0 else 0.0), round(self.samples / self.n_pixels)
        if self.quiet or (elapsed - self.last < 0.5 and passes != self.total) or passes == self.shown == self.total:
            return
        self.last, self.shown = elapsed, passes
        if self.total:
            frac = min(1.0, passes / self.total)  # adaptive: passes may go beyond the spp
            eta = elapsed * (1 - frac) / frac if frac > 0 else 0.0
        else:
            frac = min(1.0, elapsed / self.time_limit)
            eta = max(0.0, self.time_limit - elapsed)
        bar = "#" * int(24 * frac) + "-" * (24 - int(24 * frac))
        line = (f"[{bar}] {passes}/{self.total or '?'} spp  {_clock(elapsed)} elapsed  ETA {_clock(eta)}  "
                f"{rate / 1e6:.3f} Msamples/s")
        for r in self.rows or ():
            sps = r["samples_per_second"]
            name = r["device"].split(" (")[0][:28]
            state = "failed" if r["failed"] else f"{sps / 1e6:.3f} Ms/s" if sps else "starting"
            line += f"  | {name}: {state} {100 * r['share']:.0f}%"
        click.echo(("\r" + line) if self.tty else line, err=True, nl=not self.tty)

    def done(self):
        if self.tty and not self.quiet:
            click.echo("", err=True)


def _clock(seconds):
    seconds = int(seconds)
    return f"{seconds // 60:02d}:{seconds % 60:02d}" if seconds < 3600 else f"{seconds // 3600}h{seconds // 60 % 60:02d}m"
