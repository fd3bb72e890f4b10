"""kill -9 at any point of the writers of ``train``, ``evaluate`` and ``experiment``:
the command run again (with ``--resume`` where it has one) leaves the same files, byte for byte,
as a run that was never interrupted, and nothing half-written or staged. The kill points are
chosen over the whole run: every change the command makes below its folder is counted in an
uninterrupted run (``kill_points.counting``), and a copy is killed with SIGKILL right before a
chosen change (``kill_points.killed_at``): in the middle, right after the last append (a run
killed there kept a stale optimizer_state.npz, and its temporary, after the resume) and before
the very last change (an evaluation killed there kept its chunks.jsonl)."""

import json
import shutil
import signal
from pathlib import Path

import numpy as np
import pytest

from cli_helpers import invoke
from kill_points import counting, kill_points, killed_at

TRAIN = ["push", "--budget", 12, "--batch-size", 6, "--init", 6, "--worlds", 2, "--episode-seconds", 0.5, "--engine", "native",
         "--workers", 1, "--quiet"]
EVALUATE = ["--per-config", 1, "--random", 1, "--batch-size", 4, "--workers", 1]
QUICK_GP = ["n_raw=64", "n_restarts=2", "n_opt_steps=10", "fit_starts=1", "fit_steps=10"]
EXPERIMENT = ["push", "--repeats", 1, "--budget", 4, "--batch-size", 2, "--init", 2, "--worlds", 1, "--episode-seconds", 0.2,
              "--per-config", 1, "--random", 1, "--quiet", "--protocol", "paper", "--confirm-per-config", 0, "--engine",
              "native", "--workers", 1, *(a for option in QUICK_GP for a in ("--optimizer-option", option))]
# what differs between two runs that were never interrupted: who held the lock, and the wall times
# an experiment keeps (state.json) and reports
NOT_COMPARED = {".lock", "state.json", "report.json", "report.md"}
# where each command is killed (kill_points.kill_points): train's middle is killed by
# tests/cli/test_train.py too; each point costs a process start and a rerun (the suite's time)
POINTS = {"train": ["middle", "after the last append", "last"], "evaluate": ["after the last append", "last"],
          "experiment": ["after the last append", "last"]}


def files(folder: Path) -> dict:
    """Every file below ``folder`` (relative path -> bytes; an optimizer state: its arrays,
    as NPZ stores the time it was written), but those in ``NOT_COMPARED``."""
    out = {}
    for path in sorted(Path(folder).rglob("*")):
        if path.is_dir() or path.name in NOT_COMPARED:
            continue
        key = str(path.relative_to(folder))
        if path.suffix == ".npz":
            with np.load(path) as npz:
                out[key] = {k: (npz[k].dtype.str, npz[k].shape, npz[k].tobytes()) for k in npz.files}
        else:
            out[key] = path.read_bytes()
    return out


def uninterrupted(tmp_path_factory, name: str, module: str, args, before=None) -> tuple[Path, dict[str, int]]:
    """The command run whole in a folder of its own (``before(folder)`` first): (folder, where
    to kill it)."""
    from importlib import import_module

    root = tmp_path_factory.mktemp(name)
    if before is not None:
        before(root)
    with counting(root) as seen:
        assert import_module(f"mjxskill.cli.{module}").main([str(a) for a in args(root)]) == 0
    return root, kill_points(seen)


def killed_then_run_again(capsys, root: Path, points: dict[str, int], point: str, module: str, first, again) -> None:
    """Kills ``module first(root)`` at ``points[point]``, then runs ``module again(root)`` to the end."""
    done = killed_at(points[point], root, module, *first(root))
    assert done.returncode == -signal.SIGKILL, done.stderr[-3000:]
    code, err = invoke(capsys, module, *again(root))
    assert code == 0, err


# the commands that make a folder of their own and resume it: the uninterrupted run's fixture, the
# arguments, the folder, and the file that says it is there (then --resume, else made anew)
RESUMED = {"train": ("trained", TRAIN, "run", "config.yaml"), "experiment": ("experimented", EXPERIMENT, "exp",
                                                                            "experiment.yaml")}


def made_or_resumed(module: str):
    """(how ``module`` is first run in a folder, how it is run again: --resume once its folder is there)."""
    _, args, name, marker = RESUMED[module]
    first = lambda root: [*args, "--out", root / name]  # noqa: E731
    return first, lambda root: (["push", "--resume", root / name, "--quiet", "--workers", 1]
                                if (root / name / marker).exists() else first(root))


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    return uninterrupted(tmp_path_factory, "train", "train", made_or_resumed("train")[0])


@pytest.fixture(scope="module")
def experimented(tmp_path_factory):
    return uninterrupted(tmp_path_factory, "experiment", "experiment", made_or_resumed("experiment")[0])


@pytest.mark.parametrize("module, point", [(m, p) for m in RESUMED for p in POINTS[m]])
def test_train_and_experiment_killed_at_any_write_resume_to_the_same_files(request, tmp_path, capsys, module, point):
    reference, points = request.getfixturevalue(RESUMED[module][0])
    killed_then_run_again(capsys, tmp_path, points, point, module, *made_or_resumed(module))
    assert files(tmp_path) == files(reference)
    if module == "experiment":  # what its report says, but its wall times
        ours, theirs = (json.loads((d / "exp" / "report.json").read_text()) for d in (tmp_path, reference))
        assert ours["groups"] == theirs["groups"] and ours["picked"] == theirs["picked"]


@pytest.fixture(scope="module")
def evaluated(trained, tmp_path_factory):
    return uninterrupted(tmp_path_factory, "evaluate", "evaluate", lambda root: [root / "run", *EVALUATE],
                         before=lambda root: shutil.copytree(trained[0] / "run", root / "run"))


@pytest.mark.parametrize("point", POINTS["evaluate"])
def test_evaluate_killed_at_any_write_runs_again_to_the_same_files(trained, evaluated, tmp_path, capsys, point):
    reference, points = evaluated
    shutil.copytree(trained[0] / "run", tmp_path / "run")
    command = lambda root: [root / "run", *EVALUATE]  # noqa: E731
    killed_then_run_again(capsys, tmp_path, points, point, "evaluate", command, command)
    assert files(tmp_path) == files(reference)
