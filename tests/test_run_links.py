"""A run directory's files are never written through a symbolic link (issue 33, must-hold 2, in
part): the lock, evaluations.csv (appended), files replaced whole (pareto.csv, ...) and the
export folder refuse a link with one error naming it, and the file it points to is unchanged."""

from mjxskill.evaluation.render import default_gl

default_gl()

import pytest  # noqa: E402

from cli_helpers import error_line, invoke  # noqa: E402
from explore_runs import evaluations, make_push_run, push_config  # noqa: E402
from mjxskill.errors import RunError  # noqa: E402
from mjxskill.runs.run_lock import lock_run  # noqa: E402

USERS = "a file of the user's\n"


@pytest.fixture
def run_and_outside(tmp_path):
    run = make_push_run(tmp_path / "push-0")
    outside = tmp_path / "outside.txt"
    outside.write_text(USERS)
    return run, outside


def _link(run, name, target):
    path = run.path / name
    path.unlink(missing_ok=True)
    path.symlink_to(target)
    return path


def test_the_lock_is_never_taken_through_a_link(run_and_outside):
    run, outside = run_and_outside
    link = _link(run, ".lock", outside)
    with pytest.raises(RunError, match=f"{link} is a symbolic link"):
        lock_run(run.path)
    assert outside.read_text() == USERS


def test_evaluations_are_never_appended_through_a_link(run_and_outside):
    run, outside = run_and_outside
    link = _link(run, "evaluations.csv", outside)
    with pytest.raises(RunError, match=f"{link} is a symbolic link"):
        run.append(evaluations(push_config(), 1))
    assert outside.read_text() == USERS


def test_a_file_replaced_whole_is_never_written_through_a_link(run_and_outside):
    from mjxskill.runs.atomic_write import write_text

    run, outside = run_and_outside
    link = _link(run, "pareto.csv", outside)
    with pytest.raises(RunError, match=f"{link} is a symbolic link"):
        write_text(link, "new\n")
    planted = _link(run, "run_state.json.tmp", outside)  # its temporary name, planted as a link
    write_text(run.path / "run_state.json", "{}\n")
    assert outside.read_text() == USERS and not planted.exists() and (run.path / "run_state.json").read_text() == "{}\n"


def test_select_never_exports_through_a_linked_folder(run_and_outside, tmp_path, capsys):
    run, _ = run_and_outside
    users_folder = tmp_path / "my-folder"
    users_folder.mkdir()
    link = _link(run, "selected-0", users_folder)
    code, err = invoke(capsys, "select", run.path, "--pick", 0, "--no-render")
    error_line(code, err, "select", str(link), "is a symbolic link")
    assert list(users_folder.iterdir()) == []
