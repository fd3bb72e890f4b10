"""The progress of a training run on the command line (``train``, ``experiment``): a tqdm bar
with ETA, evaluations, hypervolume and best success rate, or with ``--quiet`` one log line per
batch. What ``mjxskill.training.loop.train`` reports to (its ``Progress`` protocol)."""

from __future__ import annotations

import math
import sys
import time
from typing import Any

import numpy as np
from tqdm import tqdm

from mjxskill.gp.pareto import hypervolume
from mjxskill.runs.run_dir import Evaluations


class Progress:
    """A tqdm bar with ETA, evaluations, hypervolume and best success rate; or, quiet, one log
    line per batch."""

    def __init__(self, total: int, quiet: bool, label: str = ""):
        self.total, self.quiet, self.label = total, quiet, label
        self.bar: Any = None  # the tqdm bar, once started
        self.t0 = time.monotonic()

    def _fields(self, ev: Evaluations, ref) -> dict:
        current = ev.current()
        hv = hypervolume(-ev.objectives[current], ref) if ref is not None and len(ev) else float("nan")
        best = float(np.max(ev.success_rate[current])) if len(ev) else float("nan")
        return {"hv": f"{hv:.4g}" if math.isfinite(hv) else "warm-up", "best_success": f"{best:.0%}" if len(ev) else "-"}

    def start(self, ev: Evaluations, ref) -> None:
        if self.quiet:
            return
        self.bar = tqdm(total=self.total, initial=len(ev), desc=self.label or "evaluations", unit="eval", file=sys.stderr, dynamic_ncols=True)
        self.bar.set_postfix(self._fields(ev, ref))

    def update(self, new: Evaluations, ev: Evaluations, ref) -> None:
        fields = self._fields(ev, ref)
        if self.bar is not None:
            self.bar.set_postfix(fields, refresh=False)
            self.bar.update(len(new))
        else:
            elapsed = time.monotonic() - self.t0
            print(f"{self.label}{len(ev)}/{self.total} evaluations, hypervolume {fields['hv']}, "
                  f"best success {fields['best_success']}, {elapsed:.0f} s", flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
