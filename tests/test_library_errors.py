"""The library raises the error kinds of mjxskill.errors, never the command line's own:
CommandError (a command's flags) is raised in mjxskill.cli only, which words what the library
refuses with the flags the user typed."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "mjxskill"
LIBRARY = ("runs", "training", "evaluation", "experiment", "explore")


@pytest.mark.parametrize("package", LIBRARY)
def test_no_library_module_names_command_error(package):
    named = []
    for path in sorted((PACKAGE / package).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Name) and node.id == "CommandError" or (
                    isinstance(node, ast.alias) and node.name == "CommandError"):
                named.append(f"{path.relative_to(PACKAGE.parent)}:{getattr(node, 'lineno', '?')}")
    assert named == []


def test_the_library_kinds_are_user_errors():
    from mjxskill.errors import RequestError, ResumeConflict, RunError, SettingError, UserError

    assert issubclass(SettingError, RunError) and issubclass(ResumeConflict, RunError)
    assert issubclass(RequestError, UserError) and issubclass(RequestError, ValueError)
