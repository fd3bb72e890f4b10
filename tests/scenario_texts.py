"""Copies of the shipped scenarios for tests that edit them: the text with the scene path made
absolute, so that an edited copy written anywhere (a tmp_path) still finds its MJCF scene."""

from pathlib import Path

from mjxskill.scenario import SCENARIO_DIR


def shipped_text(name: str) -> str:
    text = (SCENARIO_DIR / f"{name}.yaml").read_text()
    relative = f"scene: ../{name}.xml"
    assert text.count(relative) == 1, f"{name}.yaml no longer names its scene as {relative!r}"
    return text.replace(relative, f"scene: {(SCENARIO_DIR.parent / f'{name}.xml').resolve()}")


def write_copy(folder: Path, name: str, text: str | None = None, file_name: str | None = None) -> Path:
    """Writes ``text`` (default: the shipped scenario ``name``) to ``folder``; returns its path."""
    path = Path(folder) / (file_name or f"{name}.yaml")
    path.write_text(shipped_text(name) if text is None else text)
    return path
