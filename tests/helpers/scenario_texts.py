"""Copies of the shipped scenarios for tests that edit them: the text with the scene path and the
skill library made absolute, so that an edited copy written anywhere (a tmp_path) still finds its
MJCF scene and its skills (or the edited library copy given)."""

from pathlib import Path

from mjxskill.scenario import SCENARIO_DIR

LIBRARY = (SCENARIO_DIR.parent / "skills" / "library.yaml").resolve()
LIBRARY_LINE = "skill_library: ../skills/library.yaml"


def library_text() -> str:
    return LIBRARY.read_text()


def shipped_text(name: str, library: Path | None = None) -> str:
    text = (SCENARIO_DIR / f"{name}.yaml").read_text()
    relative = f"scene: ../{name}.xml"
    assert text.count(relative) == 1, f"{name}.yaml no longer names its scene as {relative!r}"
    text = text.replace(relative, f"scene: {(SCENARIO_DIR.parent / f'{name}.xml').resolve()}")
    if LIBRARY_LINE in text:
        text = text.replace(LIBRARY_LINE, f"skill_library: {library or LIBRARY}")
    return text


def write_copy(folder: Path, name: str, text: str | None = None, file_name: str | None = None) -> Path:
    """Writes ``text`` (default: the shipped scenario ``name``) to ``folder``; returns its path."""
    path = Path(folder) / (file_name or f"{name}.yaml")
    path.write_text(shipped_text(name) if text is None else text)
    return path


def write_library_copy(folder: Path, name: str, library: str) -> Path:
    """The shipped scenario ``name`` in ``folder`` including the skill library text ``library``
    (written beside it as library.yaml); returns the scenario's path."""
    path = Path(folder) / "library.yaml"
    path.write_text(library)
    return write_copy(folder, name, shipped_text(name, path))
