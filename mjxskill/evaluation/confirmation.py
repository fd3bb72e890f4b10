"""The pick confirmed: the picked solution and the operators' sets in many fresh worlds.

The evaluation (``evaluate_run``) rolls every Pareto solution out in a few worlds per start
configuration (the paper's 5), enough to compare groups, not to tell 96 % from 90 % for one
solution (its standard error over 50 unseen worlds is 3 to 4 points). The confirmation rolls
out only what a user would put on the robot, the pick, beside the scenario's operator sets, in
``per_config`` worlds from every known and unseen start configuration (20: a standard error
under a point over ten repetitions' unseen worlds), the same worlds for all of them, drawn from
the repetition's seed on a stream of its own (``STREAM``). ``RUN_DIR/evaluation/confirmation.json``
holds it (the evaluation's document, ``evaluate_run.evaluation_document``), made whole, and is
reused while its settings and candidates are the same; a killed confirmation is made again.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from mjxskill._files import is_regular
from mjxskill.errors import RunError
from mjxskill.evaluation.baselines import Candidates, Evaluation, evaluate_candidates
from mjxskill.evaluation.evaluate_run import FOLDER, evaluation_document, read_evaluation
from mjxskill.runs.atomic_write import make_folder, write_json

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.engine.protocol import Rollout
    from mjxskill.task import PlannedTask

FILE = "confirmation.json"
FORMAT = "mjxskill.confirmation/1"
STREAM = 0xC0F1  # the confirmation worlds' PRNG stream (evaluation 0xE7A1, race 0x2ACE)
PICKED = "picked"


def confirmation_settings(per_config: int, seed: int, engine: str, episode_seconds: float) -> dict:
    """What a confirmation's numbers depend on besides its candidates."""
    return {"per_config": int(per_config), "seed": int(seed), "engine": str(engine),
            "episode_seconds": float(episode_seconds)}


def confirmation_candidates(task: PlannedTask, picked: np.ndarray | None) -> Candidates:
    """The picked parameters (None: no pick) and the operator sets of ``task``."""
    manual = dict(task.manual_parameters)
    names = ([PICKED] if picked is not None else []) + list(manual)
    groups = ([PICKED] if picked is not None else []) + ["manual"] * len(manual)
    rows = ([np.asarray(picked, np.float64)] if picked is not None else []) + [np.asarray(v, np.float64)
                                                                             for v in manual.values()]
    return Candidates(tuple(names), tuple(groups), np.reshape(np.array(rows, np.float64), (len(names), -1)))


def confirm(run_path, rollout: Rollout, candidates: Candidates, settings: dict, batch_size: int) -> tuple[Evaluation, bool]:
    """The confirmation of ``candidates`` (reused when current, else rolled out and written).
    Returns (it, whether it was reused)."""
    old = load_confirmation(run_path, candidates, settings)
    if old is not None:
        return old, True
    # MJX: calls of batch_size rows (one compiled shape); native: all candidates in one call
    size = batch_size if settings["engine"] == "mjx" else max(1, len(candidates.names))
    ev = evaluate_candidates(rollout, candidates, settings["per_config"], settings["seed"], size, stream=STREAM)
    make_folder(Path(run_path), Path(run_path) / FOLDER)  # never through a link below the run
    write_json(Path(run_path) / FOLDER / FILE, {"format": FORMAT, "settings": settings, **evaluation_document(ev)},
               root=Path(run_path))
    return ev, False


def load_confirmation(run_path, candidates: Candidates | None, settings: dict) -> Evaluation | None:
    """The confirmation on disk with ``settings`` (and, given, ``candidates``); None when there is
    none or it is of other settings or candidates. RunError when the file is damaged."""
    path = run_path / FOLDER / FILE
    if not is_regular(path, RunError):
        return None
    ev, own = read_evaluation(path, FORMAT, "confirmation", "delete it (it is made again)")
    if own != settings:
        return None
    if candidates is not None and (ev.candidates.names != candidates.names or
                                   not np.array_equal(ev.candidates.params, candidates.params)):
        return None
    return ev


__all__ = ["FILE", "FORMAT", "PICKED", "STREAM", "confirm", "confirmation_candidates", "confirmation_settings",
           "load_confirmation"]
