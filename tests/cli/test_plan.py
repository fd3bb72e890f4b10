"""The ``plan`` and ``train`` commands through the real CLI (subprocesses): what they print, the
exported PDDL, and bad input as one line on stderr with exit code 2 and no traceback."""

import re
import subprocess
from pathlib import Path

import pytest
from fast_downward import fast_downward_plan

from cli_helpers import run_cli
from mjxskill.scenario import SCENARIO_DIR
from scenario_texts import shipped_text


def cli(module: str, *args: str) -> subprocess.CompletedProcess:
    return run_cli(module.removeprefix("mjxskill."), *args, timeout=120)


def assert_bad_input(run: subprocess.CompletedProcess, *fragments: str) -> None:
    assert run.returncode == 2, run.stderr
    assert "Traceback" not in run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1, run.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def test_plan_push_prints_goal_plan_tree_and_parameters():
    run = cli("mjxskill.plan", "push")
    assert run.returncode == 0, run.stderr
    out = run.stdout
    assert "goal: (skiros:at skiros:ObjectToBePushed-1 skiros:ObjectGoalPose-1)" in out
    assert "1. GoToLinear(robot=iiwa-1, from=Home-1, target=ObjectToBePushed-1)" in out
    assert "2. Push(robot=iiwa-1, workpiece=ObjectToBePushed-1, goal=ObjectGoalPose-1)" in out
    for symbol in ("->* plan", "-> GoToLinear", "||FS Push.start", "||FS Push.goal"):
        assert symbol in out
    assert "Push.offset_x_start  [-0.3, 0.3] m" in out and "Push.offset_y_goal   [-0.3, 0.3] m" in out


DATA = Path(__file__).resolve().parent / "data"


@pytest.mark.parametrize("task", ["push", "peg"])
def test_the_trees_from_the_yaml_skill_library_are_the_trees_python_built(task):
    # tests/cli/data/plan_<task>.txt: the command's output (after its first line, which names the
    # scenario's path) when the skills' trees were built in Python (commit f26d09d); the peg's
    # with the spiral's pitch a constant (the paper learns three parameters), and its approach
    # done 5 mm from its pose and its pitch 1.5 mm (peg.yaml's skill_parameters)
    run = cli("mjxskill.plan", task)
    assert run.returncode == 0, run.stderr
    assert run.stdout.splitlines()[1:] == (DATA / f"plan_{task}.txt").read_text().splitlines()


def test_no_skill_is_named_in_the_python_package():
    # every skill, tree included, comes from YAML: no Python module under mjxskill/ names one
    import yaml

    files = [*SCENARIO_DIR.glob("*.yaml"), *(SCENARIO_DIR.parent / "skills").glob("*.yaml")]
    names = set()
    for path in files:
        document = yaml.safe_load(path.read_text())
        names |= set(document.get("skills") or {})
    assert {"GoToLinear", "Push", "PegInsertion"} <= names
    package = Path(__file__).resolve().parents[2] / "mjxskill"
    pattern = re.compile(r"\b(" + "|".join(map(re.escape, sorted(names))) + r")\b")
    found = [f"{path.relative_to(package.parent)}:{i}: {line.strip()}" for path in sorted(package.rglob("*.py"))
             for i, line in enumerate(path.read_text().splitlines(), start=1) if pattern.search(line)]
    assert found == []


def test_plan_peg_with_a_goal_exports_pddl_fast_downward_solves(tmp_path):
    out_dir = tmp_path / "out"
    run = cli("mjxskill.plan", "peg", "--goal", "(skiros:at skiros:Peg-1 skiros:BoxWithHole-1)", "--export", str(out_dir))
    assert run.returncode == 0, run.stderr
    assert "2. PegInsertion(robot=iiwa-1, peg=Peg-1, box=BoxWithHole-1)" in run.stdout
    assert "PegInsertion.force" in run.stdout and "[-10, 0] N" in run.stdout
    domain, problem = (out_dir / "domain.pddl").read_text(), (out_dir / "problem.pddl").read_text()
    assert fast_downward_plan(domain, problem) == [
        "(gotolinear iiwa-1 home-1 boxwithhole-1)",
        "(peginsertion iiwa-1 peg-1 boxwithhole-1)",
    ]


def test_unknown_task():
    assert_bad_input(cli("mjxskill.plan", "pusj"), "unknown task 'pusj'", "available: peg, peg_square, push")
    assert_bad_input(cli("mjxskill.train", "pusj"), "mjxskill.train: error: unknown task 'pusj'")


def test_invalid_scenario_names_file_key_and_line(tmp_path):
    path = tmp_path / "mine.yaml"
    path.write_text(shipped_text("push").replace("    mass: 2.5", "    mass: -2.5"))
    assert_bad_input(cli("mjxskill.plan", str(path)), str(path), "objects.ObjectToBePushed-1.mass (line", "positive")


@pytest.mark.parametrize(
    "goal, fragment",
    [
        ("(skiros:at skiros:Peg-2 skiros:BoxWithHole-1)", "unknown object 'peg-2' in (at peg-2 boxwithhole-1); did you mean peg-1?"),
        ("(skiros:in skiros:Peg-1 skiros:BoxWithHole-1", "unbalanced parentheses"),
        ("(at peg-1 table-1)", "no plan reaches the goal '(at peg-1 table-1)'"),
    ],
)
def test_bad_goal(goal, fragment):
    assert_bad_input(cli("mjxskill.plan", "peg", "--goal", goal), fragment)


def test_unwritable_export_folder(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert_bad_input(cli("mjxskill.plan", "peg", "--export", str(blocker / "out")), "cannot write the PDDL files")


def test_missing_task_argument_is_a_usage_error():
    run = cli("mjxskill.plan")
    assert run.returncode == 2 and "usage:" in run.stderr and "Traceback" not in run.stderr
