"""A run directory's files are never written through a symbolic link: the lock,
evaluations.csv (appended), files replaced whole (pareto.csv, ...) and the export folder refuse
a link with one error naming it, and the file it points to is unchanged."""

from mjxskill.evaluation.render import default_gl

default_gl()

import json  # noqa: E402
import shutil  # noqa: E402

import pytest  # noqa: E402

from cli_helpers import error_line, invoke, snapshot  # noqa: E402
from explore_runs import evaluations, make_push_run, push_config  # noqa: E402
from mjxskill.errors import RunError  # noqa: E402
from mjxskill.runs.atomic_write import append_text, write_json  # noqa: E402
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


# -- reads: a link that leaves the directory is refused before anything is read -----------------
READERS = {  # command -> its arguments before/after the run directory
    "evaluate": ([], ["--per-config", 1, "--random", 0]),
    "select": ([], ["--no-render"]),
    "explore": ([], ["--port", 0]),
    "train": (["push", "--resume"], []),
}


def _readers(command, run):
    before, after = READERS[command]
    return [*before, run.path, *after]


@pytest.mark.parametrize("command", list(READERS))
@pytest.mark.parametrize("what", ["explore folder", "evaluation file", "config.yaml"])
def test_a_link_out_of_the_run_is_refused_before_it_is_read(run_and_outside, tmp_path, capsys, command, what):
    run, outside = run_and_outside
    if what == "explore folder":
        elsewhere = tmp_path / "elsewhere"
        elsewhere.mkdir()
        (elsewhere / "worlds.json").write_text("{}")
        link = _link(run, "explore", elsewhere)
    elif what == "evaluation file":
        (run.path / "evaluation").mkdir()
        link = _link(run, "evaluation/evaluation.json", outside)
    else:
        users_config = tmp_path / "config.yaml"
        users_config.write_text((run.path / "config.yaml").read_text())
        link = _link(run, "config.yaml", users_config)
    before = snapshot(run.path)
    code, err = invoke(capsys, command, *_readers(command, run))
    error_line(code, err, command, str(link), "is a symbolic link", "that leaves")
    assert snapshot(run.path) == before and outside.read_text() == USERS


def test_a_sub_run_linked_out_of_a_repeated_run_is_refused(tmp_path, capsys):
    import shutil

    from explore_runs import make_repeated_run

    root = make_repeated_run(tmp_path / "push-x3")
    moved = tmp_path / "seed-1-elsewhere"
    shutil.move(root.path / "seed-1", moved)
    (root.path / "seed-1").symlink_to(moved)
    for command in ("select", "train"):
        code, err = invoke(capsys, command, *(["push", "--resume"] if command == "train" else []), root.path)
        error_line(code, err, command, str(root.path / "seed-1"), "that leaves")


def test_a_link_that_stays_inside_the_run_is_read(run_and_outside, capsys):
    run, _ = run_and_outside
    (run.path / "notes.txt").symlink_to("plan.txt")  # relative, inside
    (run.path / "front.csv").symlink_to(run.path / "pareto.csv")  # absolute, inside
    code, err = invoke(capsys, "select", run.path, "--no-render")
    assert code == 0, err


@pytest.mark.parametrize("given_root", [False, True])
def test_a_folder_swapped_for_a_link_inside_a_locked_experiment_is_refused(tmp_path, given_root):
    """While a command holds an experiment's lock, a repetition's folder swapped for a link (to a
    folder outside, or to another repetition) is refused at the next write, whether the writer
    names the repetition as its root or no root at all: nothing is written through it."""
    exp = tmp_path / "exp"
    seed = exp / "optimizer" / "seed-3"
    seed.mkdir(parents=True)
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    with lock_run(exp):
        write_json(seed / "state.json", {"batch": 1}, root=seed if given_root else None)
        shutil.rmtree(seed)
        seed.symlink_to(outside)
        with pytest.raises(RunError, match="seed-3 is a symbolic link"):
            write_json(seed / "state.json", {"batch": 2}, root=seed if given_root else None)
        with pytest.raises(RunError, match="seed-3 is a symbolic link"):
            append_text(seed / "evaluations.csv", "1,2\n", root=seed if given_root else None)
    assert list(outside.iterdir()) == []
    # the lock released, the folder the caller names is its own again (a link to it is followed)
    write_json(seed / "state.json", {"batch": 3}, root=seed if given_root else None)
    assert json.loads((outside / "state.json").read_text()) == {"batch": 3}
