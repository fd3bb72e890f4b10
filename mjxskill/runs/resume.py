"""Resuming a run without losing a row: what of evaluations.csv is used, and what is set aside.

A resume uses every complete batch on disk, wherever it stands in the file, and evaluates again
only the batches that are missing or incomplete (the batch is the unit of evaluation: its
worlds are drawn per position in the batch). Nothing is dropped silently: when a line cannot
be used (a row with a wrong field count, a value that is not a number, a row cut short by a
kill, a row of an incomplete batch, a second copy of a batch) or the batches are out of order,

* the file as it was is kept beside it as ``evaluations.csv.orig-<n>`` (byte for byte),
* each unused line goes to ``evaluations-set-aside.csv`` with its line number and the reason,
* ``evaluations.csv`` is rewritten with the complete batches in batch order,

and a ``Notice`` warning says how many rows and why (the command line prints it on stderr).
Non-finite objectives of a finished batch are results (a diverged world): kept, and reported.
"""

from __future__ import annotations

import csv
import io
import os
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

from mjxskill.errors import Notice, RunError
from mjxskill.runs.atomic_write import append_text, keep_copy
from mjxskill.runs.run_dir import EVALUATIONS, Evaluations, Run, RunConfig, concat_all

SET_ASIDE = "evaluations-set-aside.csv"


def resume_batches(run: Run, config: RunConfig) -> dict[int, Evaluations]:
    """The complete batches of ``run`` (batch index -> rows), after setting aside what cannot be
    used (see the module docstring). Warns (``Notice``) about anything set aside or non-finite."""
    batches = run.batches(config)
    if batches.rejected or not batches.in_order or batches.legacy:
        kept = _keep_original(run.path / EVALUATIONS)
        if batches.rejected:
            _append_set_aside(run.path / SET_ASIDE, kept.name, batches.rejected)
        run.write_evaluations(config, concat_all(batches.complete.values(), len(config.parameter_names),
                                                 len(config.objective_names), config.pooled))
        what = (f"{_rows(len(batches.rejected))} of {run.path / EVALUATIONS} set aside in {SET_ASIDE}: "
                f"{_reasons(batches.rejected)}" if batches.rejected else
                f"the batches of {run.path / EVALUATIONS} were out of order and are rewritten in order"
                if not batches.in_order else "")
        if batches.legacy:  # a run from before contact forces were measured: the new columns
            what = "; ".join(filter(None, [what, (
                f"{run.path / EVALUATIONS} was written before contact forces were measured: its max_force "
                f"(the commanded force) is now peak_commanded_force and the contact force of its "
                f"{_rows(sum(len(b) for b in batches.complete.values()))} is not known (nan)")]))
        warnings.warn(f"{what}; the file as it was is kept as {kept.name}", Notice, stacklevel=2)
    diverged = {b: int(np.sum(~np.all(np.isfinite(ev.objectives), axis=1))) for b, ev in batches.complete.items()}
    diverged = {b: n for b, n in diverged.items() if n}
    if diverged:
        n = sum(diverged.values())
        warnings.warn(f"{_rows(n)} of {run.path / EVALUATIONS} (batch {', '.join(map(str, diverged))}) "
                      f"{'has' if n == 1 else 'have'} non-finite objectives (a world diverged); kept as results",
                      Notice, stacklevel=2)
    return batches.complete


def _rows(n: int) -> str:
    return f"{n} row" if n == 1 else f"{n} rows"


def _reasons(rejected) -> str:
    counts = Counter(r.reason for r in rejected)
    shown = [f"{_rows(n)}: {reason}" if n > 1 else f"line {next(r.line for r in rejected if r.reason == reason)}: {reason}"
             for reason, n in counts.most_common(3)]
    more = len(counts) - len(shown)
    return "; ".join(shown) + (f"; and {more} other reasons" if more > 0 else "")


def _keep_original(path: Path) -> Path:
    """Keeps ``path`` as it is under the first free ``<name>.orig-<n>``; returns that path."""
    for n in range(1, 10_000):
        kept = path.with_name(f"{path.name}.orig-{n}")
        if keep_copy(path, kept.name):  # never replaces an existing file; a hard link where it can
            return kept
    raise RunError(f"cannot keep a copy of {path}: {path.name}.orig-1 to -9999 all exist")


def _append_set_aside(path: Path, original: str, rejected) -> None:
    """The ``rejected`` lines appended to ``path`` in one write (``append_text``: never through a
    link, none of them left on a full disk), under a header when the file is new."""
    fh = io.StringIO(newline="")
    writer = csv.writer(fh, lineterminator="\n")
    if not os.path.lexists(path):
        writer.writerow(["file", "line", "reason", "text"])
    for r in rejected:
        writer.writerow([original, r.line, r.reason, r.text])
    append_text(path, fh.getvalue())


__all__ = ["SET_ASIDE", "resume_batches"]
