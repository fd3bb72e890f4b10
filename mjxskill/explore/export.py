"""The page's "export": the files ``python -m mjxskill.select RUN --pick k`` writes, through the
same functions (``mjxskill.evaluation.selection``), into ``RUN/selected-<k>/``.

An export never replaces a file the user has: where ``selected-<k>/`` already holds parameter
files with other content (the run trained on and its front changed, or they were edited), it
is refused and says so. When the page has rendered the solution from known start
configuration 0 (the world ``select`` renders from by default), the rendering is copied into
the folder as select would have written it (``frames/`` or ``episode.mp4``). The export goes
through select's writer (``mjxskill.evaluation.selection.write_export``): a rendering there
already with other files (another size, frames a killed renderer left) is kept and the export
refused, as a link anywhere below the run is; nothing is written then.
"""

from __future__ import annotations

from pathlib import Path

from mjxskill.errors import RunError
from mjxskill.evaluation.selection import export_document, write_export
from mjxskill.evaluation.validation import row_validation, validated_union
from mjxskill.explore.data import RunEntry, evaluation_rows
from mjxskill.explore.solutions import Solutions
from mjxskill.runs.atomic_write import read_below


def export_solution(entry: RunEntry, k: int, solutions: Solutions | None = None) -> dict:
    """Writes ``selected-<k>/`` of ``entry``'s Pareto row ``k``; returns the paths written."""
    front = entry.front()
    if not 0 <= k < len(front):
        raise RunError(f"Pareto row {k}: {entry.run.path} has rows 0-{len(front) - 1}" if len(front)
                           else f"{entry.run.path} has an empty Pareto front")
    doc = export_document(entry.config, front, k, entry.run.path, row_validation(*validated_union([(entry.run, front)]), k))
    folder = entry.run.path / f"selected-{k}"
    rendering = None
    if solutions is not None:
        index = int(evaluation_rows(entry.evaluations(), front.take(slice(k, k + 1)))[0])
        cache = solutions.folder(entry, index)
        rendering = _cached_rendering(entry.run.path, cache, solutions.cached_video(cache, front.params[k], 0))
    hint = f"move it away, or export with python -m mjxskill.select {entry.run.path} --pick {k} --out FOLDER"
    written = write_export(doc, folder, entry.run.path, rendering, hint=hint)
    return {"folder": str(folder), "written": [str(p) for p in written]}


def _cached_rendering(run_path: Path, cache: Path, video: dict | None) -> dict | None:
    """The page's rendering in ``cache`` (as ``known-0.json`` lists it) as the export's
    ``frames`` or ``episode.mp4``: read without following a link, regular files only, each
    named inside the cache; None when the page has rendered none."""
    if video is None:
        return None
    files = video.get("files")
    if not isinstance(files, list) or not files or not all(isinstance(f, str) for f in files):
        raise RunError(f"{cache / 'known-0.json'} lists no files; remove it and render the solution again")
    paths = [cache / f for f in files]
    content = {p.name: read_below(run_path, p) for p in paths}
    if video.get("kind") == "mp4":
        return {"episode.mp4": content[paths[0].name]}
    return {"frames": content}
