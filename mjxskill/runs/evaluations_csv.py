"""The evaluation rows of a run as CSV: writing them exactly, reading them back with every row
either used or rejected with its line number and the reason, and sorting rows into batches.

Floats are written with 17 significant digits (``repr``), which round-trips float64 exactly.
Reading never drops a row silently: ``parse`` returns the rows it can use and a ``Rejected``
entry (line, text, reason) for every other line, and ``assign_batches`` sorts the usable rows
into the run's batches, rejecting duplicates and rows of batches the budget does not have. What
to do with rejected rows is the caller's (``mjxskill.runs.resume`` sets them aside;
``read_csv`` refuses a file that has any).
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from mjxskill._files import read_regular
from mjxskill.errors import RunError, quote
from mjxskill.runs.atomic_write import append_text, write_text


# The force columns after success_rate, N, each the mean over the worlds of a per-world value:
# the measured contact force's peak and mean (mjxskill.sim.tool_force) and the largest force the
# skills commanded. Runs written before contact forces were measured end with one column,
# max_force (the commanded force): they are read with the contact forces unknown (NaN).
FORCE_COLUMNS = ("peak_contact_force", "mean_contact_force", "peak_commanded_force")
LEGACY_FORCE_COLUMNS = ("max_force",)
# A run of the robust protocol (mjxskill.runs.training_protocol) pools a parameter set's worlds
# when it rolls it out again: after the force columns, how many worlds the row's values pool,
# which earlier row of the same parameter set it replaces (its index in batch order; -1: a new
# parameter set), and per objective the world-to-world standard deviation of the per-world
# value whose mean the row holds (``sd_<objective>``; the success bound's is the per-world
# success's).
POOLING_COLUMNS = ("worlds", "replaces")
SPREAD_PREFIX = "sd_"


class Evaluations(NamedTuple):
    """The rows of evaluations.csv. n rows, P parameters, O objectives.

    iteration (n,) int: batch index. params (n, P) float64. objectives (n, O) float64, larger
    is better. success_rate (n,) float64 in [0, 1]. peak_contact_force, mean_contact_force (n,)
    float64, N: the measured normal contact force between the tool and the world, its largest
    and its mean value in an episode, mean over the worlds (NaN: not measured, a run written
    before it was, or a diverged world). peak_commanded_force (n,) float64, N: the largest
    feed-forward force the skills commanded in an episode, mean over the worlds.
    """

    iteration: np.ndarray
    params: np.ndarray
    objectives: np.ndarray
    success_rate: np.ndarray
    peak_contact_force: np.ndarray
    mean_contact_force: np.ndarray
    peak_commanded_force: np.ndarray
    worlds: np.ndarray | None = None
    replaces: np.ndarray | None = None
    spread: np.ndarray | None = None

    def __len__(self) -> int:  # type: ignore[override]
        return len(self.iteration)

    @classmethod
    def empty(cls, n_params: int, n_objectives: int, pooled: bool = False) -> "Evaluations":
        """No rows; ``pooled``: with the pooling fields of the robust protocol."""
        rows = cls(np.zeros(0, int), np.zeros((0, n_params)), np.zeros((0, n_objectives)),
                   *(np.zeros(0) for _ in range(1 + len(FORCE_COLUMNS))))
        if pooled:  # not _replace: len() is rows
            rows = cls(*rows[:7], worlds=np.zeros(0, int), replaces=np.zeros(0, int), spread=np.zeros((0, n_objectives)))
        return rows

    @property
    def pooled(self) -> bool:
        """Whether the rows carry the pooling fields (a run of the robust protocol)."""
        return self.worlds is not None

    def current(self, upto: int | np.integer | None = None) -> np.ndarray:
        """(n,) bool: the rows no later row among the first ``upto`` (None: all) replaces,
        one per parameter set (every row when the rows do not pool)."""
        mask = np.ones(len(self), bool)
        if self.pooled:
            assert self.replaces is not None  # pooled rows carry every pooling field
            replaced = self.replaces[: len(self) if upto is None else upto]
            mask[replaced[(replaced >= 0) & (replaced < len(self))]] = False
        return mask

    def take(self, index) -> "Evaluations":
        fields: list[Any] = [None if a is None else np.asarray(a)[index] for a in self]
        return Evaluations(*fields)

    def concat(self, other: "Evaluations") -> "Evaluations":
        if self.pooled != other.pooled:
            raise ValueError("cannot join rows with and without the pooling fields")
        fields: list[Any] = [None if a is None else np.concatenate([a, b]) for a, b in zip(self, other)]
        return Evaluations(*fields)


def concat_all(parts, n_params: int, n_objectives: int, pooled: bool = False) -> Evaluations:
    out = Evaluations.empty(n_params, n_objectives, pooled)
    for part in parts:
        out = out.concat(part)
    return out


def _format(value: float) -> str:
    return repr(float(value))  # shortest string that round-trips the float64 exactly


def format_rows(ev: Evaluations) -> str:
    """CSV text (no header) of ``ev``."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    for i in range(len(ev)):
        pooling = []
        if ev.pooled:
            assert ev.worlds is not None and ev.replaces is not None and ev.spread is not None  # set together
            pooling = [int(ev.worlds[i]), int(ev.replaces[i]), *map(_format, ev.spread[i])]
        writer.writerow(
            [int(ev.iteration[i]), *map(_format, ev.params[i]), *map(_format, ev.objectives[i]),
             _format(ev.success_rate[i]), *(_format(getattr(ev, c)[i]) for c in FORCE_COLUMNS), *pooling]
        )
    return out.getvalue()


def write_csv(path: Path, columns: list[str], ev: Evaluations) -> None:
    """Writes a whole CSV atomically (temporary file + rename)."""
    write_text(path, ",".join(columns) + "\n" + format_rows(ev))


def append_rows(path: Path, ev: Evaluations) -> None:
    """Appends ``ev`` to a CSV and forces it to disk before returning (RunError when the CSV is a
    symbolic link: never appended to through one); when that fails (a full disk) the file is cut
    back to what it was, so no part of a batch stays."""
    append_text(path, format_rows(ev))


class Rejected(NamedTuple):
    """A line of a CSV that is not used: its 1-based line number, its text, why."""

    line: int
    text: str
    reason: str


class Parsed(NamedTuple):
    """The usable rows of a CSV (``lines``, ``texts``: the line number and text of each) and
    every other line. legacy: the file has the columns of a run written before contact forces
    were measured (``LEGACY_FORCE_COLUMNS``)."""

    rows: Evaluations
    lines: np.ndarray
    texts: list[str]
    rejected: list[Rejected]
    legacy: bool = False


def legacy_columns(columns: list[str]) -> list[str]:
    """The header a run written before contact forces were measured has for ``columns``."""
    return columns[: len(columns) - len(FORCE_COLUMNS)] + list(LEGACY_FORCE_COLUMNS)


def read_bytes(path: Path) -> bytes:
    try:
        return read_regular(path)  # a regular file only: a FIFO in its place would block forever
    except FileNotFoundError:
        raise RunError(f"{path} is missing: the run directory lost its evaluations file") from None
    except OSError as err:
        raise RunError(f"cannot read {path}: {err.strerror}") from None


def parse(data: bytes, columns: list[str], bounds, where: str) -> Parsed:
    """Rows of CSV ``data`` with the header ``columns``. ``bounds`` ((P,), (P,)): a row whose
    parameters are not finite or lie outside them cannot be told to the optimizer and is
    rejected (None: parameters are not checked); non-finite objectives are results (a diverged
    world) and are kept."""
    lines = data.split(b"\n")
    header = lines[0].decode("utf-8", "replace")
    if len(lines) == 1:
        raise RunError(f"{where} has no complete header line ({len(data)} bytes): it was cut short")
    legacy = header == ",".join(legacy_columns(columns))
    if legacy:  # the commanded force is the old max_force; the contact forces are unknown
        columns = legacy_columns(columns)
    elif header != ",".join(columns):
        got = next(csv.reader([header]), []) if header else "nothing"
        raise RunError(f"{where} does not have the columns this task expects: got {got}, expected {columns}")
    o = sum(1 for c in columns if c.startswith("objective_"))
    pooled = POOLING_COLUMNS[0] in columns
    extra = len(POOLING_COLUMNS) + o if pooled else 0  # the pooling columns after the forces
    p = len(columns) - o - 2 - (len(LEGACY_FORCE_COLUMNS) if legacy else len(FORCE_COLUMNS)) - extra
    lo: np.ndarray | None = None
    hi: np.ndarray | None = None
    tol: np.ndarray | None = None
    if bounds is not None:
        lo, hi = np.asarray(bounds, np.float64)
        tol = 1e-9 * (hi - lo)  # the optimizer's own tolerance (mjxskill.gp.tell)
    values, numbers, texts, rejected = [], [], [], []
    for number, raw in enumerate(lines[1:], start=2):
        last = number == len(lines)
        if last and raw == b"":
            break  # the file ends with a line end, as it should
        reason, row = _row(raw, columns, p, lo, hi, tol, o if pooled else None)
        if last:  # no line end after it: the process stopped while writing it
            reason = "cut short (no line end: the run was stopped while writing it)"
        if reason == "empty":
            continue
        if reason:
            rejected.append(Rejected(number, raw.decode("utf-8", "replace"), reason))
        else:
            values.append(row)
            numbers.append(number)
            texts.append(raw.decode("utf-8"))
    data_ = np.array(values, np.float64).reshape(-1, len(columns))
    forces = data_[:, 2 + p + o: len(columns) - extra]
    if legacy:
        forces = np.concatenate([np.full((len(data_), 2), np.nan), forces], axis=1)
    rows = Evaluations(data_[:, 0].astype(int), data_[:, 1 : 1 + p], data_[:, 1 + p : 1 + p + o],
                       data_[:, 1 + p + o], *forces.T)
    if pooled:
        tail = data_[:, len(columns) - extra:]
        rows = Evaluations(*rows[:7], worlds=tail[:, 0].astype(int), replaces=tail[:, 1].astype(int), spread=tail[:, 2:])
    return Parsed(rows, np.array(numbers, int), texts, rejected, legacy)


def _row(raw: bytes, columns, p: int, lo, hi, tol, o: int | None = None) -> tuple[str | None, list[float] | None]:
    """(None, values) for a usable row, else (reason, None); ("empty", None) for a blank line.
    ``o``: the number of objectives of a row with the pooling columns (None: it has none)."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        return "not UTF-8 text", None
    if not text.strip():
        return "empty", None
    fields = next(csv.reader([text]))
    if len(fields) != len(columns):
        return f"has {len(fields)} fields, expected {len(columns)}", None
    try:
        row = [float(v) for v in fields]
    except ValueError:
        bad = next(i for i, v in enumerate(fields) if not _is_number(v))
        return f"{columns[bad]} is not a number: {quote(fields[bad])}", None
    if not (row[0] >= 0 and float(row[0]).is_integer()):
        return f"iteration {quote(fields[0])} is not a batch number", None
    params = np.array(row[1 : 1 + p]) if lo is not None else ()
    for i, v in enumerate(params):
        if not math.isfinite(v):
            return f"{columns[1 + i]} = {fields[1 + i]} is not a finite number", None
        if v < lo[i] - tol[i] or v > hi[i] + tol[i]:
            return f"{columns[1 + i]} = {fields[1 + i]} is outside its bounds [{lo[i]:g}, {hi[i]:g}]", None
    if o is not None:
        at = len(columns) - len(POOLING_COLUMNS) - o
        worlds, replaces = row[at], row[at + 1]
        if not (worlds >= 1 and worlds.is_integer()):
            return f"worlds {quote(fields[at])} is not a positive whole number of worlds", None
        if not (replaces >= -1 and replaces.is_integer()):
            return f"replaces {quote(fields[at + 1])} is not a row number (or -1)", None
    return None, row


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


class Batches(NamedTuple):
    """Rows sorted into batches. complete: batch index -> its rows (exactly the batch's size).
    rejected: every line not in a complete batch (unreadable, a row of an incomplete batch, a
    further copy of a complete one, a batch beyond the budget), in line order. in_order: the
    file was exactly the complete batches, one after the other in batch order. legacy: as
    ``Parsed.legacy``."""

    complete: dict[int, Evaluations]
    rejected: list[Rejected]
    in_order: bool
    legacy: bool = False  # the file has the columns of a run from before contact forces were measured


def assign_batches(parsed: Parsed, sizes: list[int]) -> Batches:
    """Sorts ``parsed.rows`` into the batches of ``sizes`` (file order within a batch)."""
    rows, rejected = parsed.rows, list(parsed.rejected)
    keep: dict[int, list[int]] = {}
    for i, batch in enumerate(rows.iteration):
        batch = int(batch)
        if batch >= len(sizes):
            rejected.append(Rejected(int(parsed.lines[i]), parsed.texts[i],
                                     f"batch {batch} is beyond the budget (batches 0-{len(sizes) - 1})"))
        elif len(keep.setdefault(batch, [])) == sizes[batch]:
            rejected.append(Rejected(int(parsed.lines[i]), parsed.texts[i],
                                     f"a further row of batch {batch}, which already has its {sizes[batch]} rows"))
        else:
            keep[batch].append(i)
    complete = {b: rows.take(idx) for b, idx in sorted(keep.items()) if len(idx) == sizes[b]}
    for b, idx in keep.items():
        if len(idx) < sizes[b]:
            reason = f"batch {b} is incomplete ({len(idx)} of {sizes[b]} rows), so it is evaluated again"
            rejected += [Rejected(int(parsed.lines[i]), parsed.texts[i], reason) for i in idx]
    used = [i for b in complete for i in keep[b]]
    in_order = not rejected and used == list(range(len(rows))) and list(complete) == list(range(len(complete)))
    return Batches(complete, sorted(rejected), in_order, parsed.legacy)


def read_csv(path: Path, columns: list[str], bounds=None) -> Evaluations:
    """Reads a CSV written by this module: a torn last line (a kill mid-write) is ignored, any
    other line that is not a row (with ``bounds``: parameters outside them too) is a RunError
    naming the file and the line."""
    parsed = parse(read_bytes(path), columns, bounds, str(path))
    for rejected in parsed.rejected:
        if not rejected.reason.startswith("cut short"):
            raise RunError(f"{path}: line {rejected.line} {rejected.reason}")
    return parsed.rows
