"""Picking a Pareto solution and exporting it (``python -m mjxskill.select``).

A pick by constraint keeps the Pareto solutions within every given limit (``--max-force``: the
peak of the measured contact force between the tool and the world in an episode, N, mean over
the worlds; ``--min-success``) and takes the one with the highest success rate, ties broken by
the first objective. Where the runs' picks were validated (``evaluate`` of a repeated run, an
experiment: ``RUN_DIR/evaluation/validation.json``), a validated solution within the limits is
taken before any other, by its validation success (fresh worlds; a training success comes from
the few worlds of one batch and flatters a knife-edge set), and ``--min-success`` reads the
validation success of a validated solution. An experiment validates its optimizer runs' picks
only, so over an experiment its random searches' solutions come after those; ``select`` names
the best unvalidated solution when it did better in training than the validated pick. A run
written before contact forces were measured has none: ``--max-force``
is refused for it (its commanded force is no measure of what the tool did to the world). The choice is written to
``RUN_DIR/selected-<k>/parameters.yaml`` and ``parameters.json`` (parameter name -> value and
unit, ready for a controller) and rendered there (PNG frames, or an MP4 with ffmpeg). An export
never replaces a file or folder with other content (an earlier pick, a file edited by hand,
frames of another rendering) unless ``select --replace`` says so, never writes through a link
at any depth below the run (or ``--out``) and is written whole, each file or folder staged
beside its place (``mjxskill.runs.outputs.write_outputs``): ``select`` and the explore page
refuse with one error naming it; writing the same content again is harmless.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import yaml

from mjxskill.errors import RunError
from mjxskill.runs.outputs import write_outputs


def choose(front, max_force: float | None = None, min_success: float | None = None, validated=None,
           validated_seconds=None) -> int:
    """Row of ``front`` (Evaluations) meeting the limits with the best success rate, ties by
    the first objective. ``validated``: (len(front),) validation success rates, NaN where a row
    has none; a validated row meeting the limits goes first, by that rate (then the faster by
    ``validated_seconds``, its mean time to success in the validation with a failure counted as
    the whole episode, NaN where unknown; then the training success, the first objective), and
    is held to ``min_success`` by it: the experiment's pick (``pooled.pick``). Raises RunError
    when no row meets them."""
    validated = np.full(len(front), np.nan) if validated is None else np.asarray(validated, np.float64)
    has_validation = ~np.isnan(validated)
    success = np.where(has_validation, validated, front.success_rate)
    ok = np.ones(len(front), bool)
    # A NaN (a diverged world) meets no limit: it is not known to be within it.
    if max_force is not None:
        if len(front) and np.all(np.isnan(front.peak_contact_force)):
            raise RunError("--max-force limits the measured contact force, and this run has none (it was "
                               "written before contact forces were measured; its commanded force is "
                               "peak_commanded_force); pick with --pick K or --min-success, or train it again")
        ok &= front.peak_contact_force <= max_force
    if min_success is not None:
        ok &= success >= min_success
    if not ok.any():
        limits = ", ".join(f"{name} {value:g}" for name, value in (("--max-force", max_force), ("--min-success", min_success))
                           if value is not None)
        raise RunError(f"no Pareto solution meets {limits or 'the limits'}: the front's {len(front)} rows have "
                           f"peak contact forces {_span(front.peak_contact_force, '{:.1f}', ' N')} and success rates "
                           f"{_span(success, '{:.0%}', '')}"
                           + (" (the validation's where a row has one)" if has_validation.any() else ""))
    validated_ok = ok & has_validation
    rows = np.flatnonzero(validated_ok if validated_ok.any() else ok)
    seconds = np.full(len(front), np.inf) if validated_seconds is None else np.nan_to_num(
        np.asarray(validated_seconds, np.float64), nan=np.inf)
    order = np.lexsort((-front.objectives[rows, 0], -front.success_rate[rows], seconds[rows],
                        -np.nan_to_num(validated[rows], nan=0.0)))
    return int(rows[order[0]])


def best_unvalidated(front, max_force: float | None, min_success: float | None, validated) -> int | None:
    """The row :func:`choose` would take among the rows without a validation (training success
    alone), or None when none meets the limits: what ``select`` names beside a validated pick
    whose validation success is below that row's training success."""
    rows = np.flatnonzero(np.isnan(np.asarray(validated, np.float64)))
    if not len(rows):
        return None
    try:
        return int(rows[choose(front.take(rows), max_force, min_success)])
    except RunError:
        return None


def _span(values: np.ndarray, fmt: str, unit: str) -> str:
    finite = values[np.isfinite(values)]
    text = f"{fmt.format(finite.min())}-{fmt.format(finite.max())}{unit}" if len(finite) else "unknown"
    missing = len(values) - len(finite)
    return text + (f" ({missing} not a number: a diverged world)" if missing else "")


def export_document(config, front, k: int, run_path: Path, validation: tuple[float, int] | None = None) -> dict:
    """The chosen solution as plain data (YAML/JSON); ``validation``: its (success rate, worlds)
    in the pick's validation (``mjxskill.evaluation.validation.row_validation``), when it had one."""
    validated = {} if validation is None else {
        "validation_success_rate": float(validation[0]),
        "validated_in": f"{int(validation[1])} fresh worlds from the known start configurations (evaluation/validation.json)"}
    return {
        "task": config.task,
        "goal": config.goal,
        # one spelling of the run (absolute, normalized, links kept): the same pick exported again
        # through another spelling of its path writes the same document
        "run": os.path.abspath(run_path),
        "pareto_index": k,
        "parameters": {
            name: {"value": float(v), "unit": unit}
            for name, v, unit in zip(config.parameter_names, front.params[k], config.parameter_units)
        },
        "objectives": {name: float(v) for name, v in zip(config.objective_names, front.objectives[k])},
        "success_rate": float(front.success_rate[k]),
        "peak_contact_force_N": float(front.peak_contact_force[k]),
        "mean_contact_force_N": float(front.mean_contact_force[k]),
        "peak_commanded_force_N": float(front.peak_commanded_force[k]),
        "evaluated_in": f"{config.worlds} randomized worlds, {config.episode_seconds:g} s episodes",
        **validated,
    }


def export_texts(doc: dict) -> dict[str, str]:
    """File name -> text of the export of ``doc``."""
    return {"parameters.yaml": yaml.safe_dump(doc, sort_keys=False), "parameters.json": json.dumps(doc, indent=2) + "\n"}


def export_outputs(doc: dict, folder: Path, rendering: dict | None = None) -> dict[Path, bytes | dict[str, bytes]]:
    """What the export of ``doc`` into ``folder`` writes (path -> a file's bytes or a folder's
    files, for ``mjxskill.runs.outputs.write_outputs``): the parameter files and, when given,
    the ``rendering`` (name in the folder -> content: ``frames`` or ``episode.mp4``)."""
    out: dict[Path, bytes | dict[str, bytes]] = {folder / name: text.encode() for name, text in export_texts(doc).items()}
    out.update({folder / name: content for name, content in (rendering or {}).items()})
    return out


def write_export(doc: dict, folder: Path, root: Path, rendering: dict | None = None, *, replace: bool = False,
                 hint: str = "move it away, or export elsewhere", flag: str = "") -> list[Path]:
    """Writes the export of ``doc`` (and its ``rendering``) into ``folder``, below ``root`` (the
    run, or the folder the user named), through the one writer (``write_outputs``): nothing is
    written when one of its files is a link, sits below a link, or holds other content (an
    earlier pick, a file edited by hand) unless ``replace``; each file or folder is staged and
    renamed into place. RunError (with ``hint`` and ``flag``) names what is in the way."""
    return write_outputs(root, export_outputs(doc, folder, rendering), replace=replace, hint=hint, flag=flag)
