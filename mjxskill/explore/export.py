"""The page's "export": the files ``python -m mjxskill.select RUN --pick k`` writes, through the
same functions (``mjxskill.evaluation.selection``), into ``RUN/selected-<k>/``.

An export never replaces a file the user has: where ``selected-<k>/`` already holds parameter
files with other content (the run trained on and its front changed, or they were edited), it
is refused and says so. When the page has rendered the solution from known start
configuration 0 (the world ``select`` renders from by default), the rendering is copied into
the folder as select would have written it (``frames/`` or ``episode.mp4``), unless one is
there already.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from mjxskill.errors import RunError
from mjxskill.evaluation.selection import conflicting_export, export_document, what_is_there, write_export
from mjxskill.evaluation.validation import row_validation, validated_union
from mjxskill.explore.data import RunEntry, evaluation_rows
from mjxskill.explore.solutions import Solutions


def export_solution(entry: RunEntry, k: int, solutions: Solutions | None = None) -> dict:
    """Writes ``selected-<k>/`` of ``entry``'s Pareto row ``k``; returns the paths written."""
    front = entry.front()
    if not 0 <= k < len(front):
        raise RunError(f"Pareto row {k}: {entry.run.path} has rows 0-{len(front) - 1}" if len(front)
                           else f"{entry.run.path} has an empty Pareto front")
    doc = export_document(entry.config, front, k, entry.run.path, row_validation(*validated_union([(entry.run, front)]), k))
    folder = entry.run.path / f"selected-{k}"
    conflict = conflicting_export(doc, folder)
    if conflict is not None:
        raise RunError(f"{conflict} {what_is_there(conflict)}; move it away, or export with "
                       f"python -m mjxskill.select {entry.run.path} --pick {k} --out FOLDER")
    written = [str(p) for p in write_export(doc, folder)]
    if solutions is not None:
        index = int(evaluation_rows(entry.evaluations(), front.take(slice(k, k + 1)))[0])
        cache = solutions.folder(entry, index)
        written += _copy_rendering(cache, solutions.cached_video(cache, front.params[k], 0), folder)
    return {"folder": str(folder), "written": written}


def _copy_rendering(cache: Path, video: dict | None, folder: Path) -> list[str]:
    if video is None:
        return []
    if video["kind"] == "mp4":
        target = folder / "episode.mp4"
        if target.exists():
            return []
        shutil.copyfile(cache / video["files"][0], target)
        return [str(target)]
    target = folder / "frames"
    if target.exists():
        return []
    target.mkdir()
    for name in video["files"]:
        shutil.copyfile(cache / name, target / Path(name).name)
    return [str(target)]
