"""World model -> PDDL: read back with the ``pddl`` package and pyperplan, solved by Fast
Downward (an independent planner) to the same optimal plan; goals in SkiROS and plain form."""

import pytest
from fast_downward import fast_downward_plan
from hypothesis import given, settings
from hypothesis import strategies as st
from pddl.logic.base import And, Not
from pddl.parser.domain import DomainParser
from pddl.parser.problem import ProblemParser

from mjxskill.errors import GoalError
from mjxskill.planner.world_pddl import domain_pddl, goal_literals, goal_pddl, problem_pddl
from mjxskill.task import plan_task
from mjxskill.scenario import load_scenario


@pytest.fixture(scope="module")
def scenarios():
    return {name: load_scenario(name) for name in ("push", "peg")}


def _atoms(formula):
    """Ground literals of a pddl-package formula as ("at", "a", "b") / ("not", "at", ...)."""
    if isinstance(formula, And):
        return {atom for operand in formula.operands for atom in _atoms(operand)}
    if isinstance(formula, Not):
        return {("not", *atom) for atom in _atoms(formula.argument)}
    return {(formula.name, *(t.name for t in formula.terms))}


@pytest.mark.parametrize("name", ["push", "peg"])
def test_fast_downward_finds_the_same_optimal_plan(scenarios, name):
    task = plan_task(scenarios[name])
    assert fast_downward_plan(task.domain_pddl, task.problem_pddl) == list(task.plan)
    assert [step.skill for step in task.steps] == ["GoToLinear", {"push": "Push", "peg": "PegInsertion"}[name]]


@pytest.mark.parametrize("name", ["push", "peg"])
def test_domain_has_one_action_per_skill_with_its_conditions(scenarios, name):
    scn = scenarios[name]
    domain = DomainParser()(plan_task(scn).domain_pddl)
    actions = {a.name: a for a in domain.actions}
    assert set(actions) == {s.lower() for s in scn.skills}
    for skill in scn.skills.values():
        action = actions[skill.pddl_name]
        assert [v.name for v in action.parameters] == [p.name for p in skill.arguments]
        # the pddl package names variables without "?"; our conditions use "?name"
        pre = {tuple(x.lstrip("?") for x in atom) for atom in _atoms(action.precondition)}
        want = {tuple(x.lstrip("?") for x in _literal(c)) for c in (*skill.preconditions, *skill.holdconditions)}
        assert pre == want
        effects = {tuple(x.lstrip("?") for x in atom) for atom in _atoms(action.effect)}
        assert effects == {tuple(x.lstrip("?") for x in _literal(c)) for c in skill.postconditions}
    assert {p.name for p in domain.predicates} == set(scn.predicates)


def _literal(text):
    tokens = text.replace("(", " ").replace(")", " ").split()
    return tuple(tokens)


@pytest.mark.parametrize("name", ["push", "peg"])
def test_problem_holds_every_object_and_relation(scenarios, name):
    scn = scenarios[name]
    problem = ProblemParser()(plan_task(scn).problem_pddl)
    assert {o.name for o in problem.objects} == {o.lower() for o in (*scn.objects, scn.robot.name)}
    relations = {_literal(r.lower()) for r in (*scn.robot.relations, *(r for o in scn.objects.values() for r in o.relations))}
    assert {(a.name, *(t.name for t in a.terms)) for a in problem.init} == relations


def test_pyperplan_reads_the_exported_files(scenarios, tmp_path):
    from pyperplan.planner import _parse

    task = plan_task(scenarios["peg"])
    (tmp_path / "d.pddl").write_text(task.domain_pddl)
    (tmp_path / "p.pddl").write_text(task.problem_pddl)
    parsed = _parse(str(tmp_path / "d.pddl"), str(tmp_path / "p.pddl"))
    assert set(parsed.domain.actions) == {"gotolinear", "push", "peginsertion"}


def test_namespaced_and_plain_goals_are_the_same(scenarios):
    peg = scenarios["peg"]
    skiros = goal_pddl(peg, "(skiros:at skiros:Peg-1 skiros:BoxWithHole-1)")
    assert skiros == goal_pddl(peg, "(at peg-1 boxwithhole-1)") == "(and (at peg-1 boxwithhole-1))"
    assert goal_pddl(peg, "(and (at peg-1 boxwithhole-1) (ee-at iiwa-1 boxwithhole-1))") == (
        "(and (at peg-1 boxwithhole-1) (ee-at iiwa-1 boxwithhole-1))"
    )


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_goal_reading_ignores_case_namespaces_and_spacing(scenarios, data):
    peg = scenarios["peg"]
    tokens = ["at", "Peg-1", "BoxWithHole-1"]
    written = []
    for token in tokens:
        token = "".join(data.draw(st.sampled_from([ch.lower(), ch.upper()])) for ch in token)
        if data.draw(st.booleans()):
            token = data.draw(st.sampled_from(["skiros:", "SkiROS:", "cora:"])) + token
        written.append(token)
    space = st.text(alphabet=" \t\n", min_size=1, max_size=3)
    goal = data.draw(st.text(alphabet=" \n", max_size=2)) + "(" + data.draw(space).join(written) + ")"
    assert goal_literals(peg, goal) == ((True, "at", ("peg-1", "boxwithhole-1")),)


def test_negated_goal_needs_negative_preconditions_and_fast_downward_solves_it(scenarios):
    peg = scenarios["peg"]
    goal = "(and (skiros:at skiros:Peg-1 skiros:BoxWithHole-1) (not (ee-at iiwa-1 home-1)))"
    assert ":negative-preconditions" not in plan_task(peg).domain_pddl
    domain = domain_pddl(peg, negative_goal=True)
    assert ":negative-preconditions" in domain
    assert "(not (ee-at iiwa-1 home-1))" in problem_pddl(peg, goal)
    assert len(fast_downward_plan(domain, problem_pddl(peg, goal))) == 2


def test_another_goal_in_the_same_world(scenarios):
    # Only going to the box: one GoToLinear and nothing to learn.
    task = plan_task(scenarios["peg"], "(ee-at iiwa-1 boxwithhole-1)")
    assert [str(s) for s in task.steps] == ["GoToLinear(robot=iiwa-1, from=Home-1, target=BoxWithHole-1)"]
    assert task.parameters == () and task.bounds.shape == (2, 0)


@pytest.mark.parametrize(
    "goal, message",
    [
        ("(skiros:att skiros:Peg-1 skiros:BoxWithHole-1)", r"unknown predicate 'att'; did you mean at\b"),
        ("(at Peg-2 BoxWithHole-1)", "unknown object 'peg-2'.*did you mean peg-1"),
        ("(at peg-1 box-with-hole-1)", "unknown object 'box-with-hole-1'.*did you mean boxwithhole-1"),
        ("(at peg-1)", "takes 2 arguments"),
        ("(at home-1 peg-1)", "'home-1' is a pose"),
        ("(at peg-1 boxwithhole-1", "unbalanced parentheses: 1 '\\(' not closed"),
        ("(at peg-1 boxwithhole-1))", "unbalanced parentheses: unexpected '\\)' at column 25"),
        ("", "empty goal"),
        ("   ", "empty goal"),
        ("at peg-1 boxwithhole-1", "parenthesised"),
        ("()", "not valid PDDL"),
        ("(at peg-1 (boxwithhole-1))", "not valid PDDL"),
        ("(or (at peg-1 boxwithhole-1) (at peg-1 home-1))", "disjunctive"),
    ],
)
def test_bad_goals_are_named(scenarios, goal, message):
    with pytest.raises(GoalError, match=message) as info:
        goal_literals(scenarios["peg"], goal)
    assert repr(goal) in str(info.value) or "empty goal" in str(info.value)
