"""Classic PDDL domains and problems used by the planner tests and benchmark.

Each entry of `CASES` names the independent planner that can read it: ``"pyperplan"`` (STRIPS +
typing) or ``"fd"`` (Fast Downward: also negative preconditions and equality, but not
`either`). tests/planner/test_domains.py checks that pyperplan's cases stay inside pyperplan's
language, so a case it would misread cannot pass silently.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from importlib.util import find_spec
from typing import NamedTuple

GRIPPER_DOMAIN = """
(define (domain gripper-strips)
  (:predicates (room ?r) (ball ?b) (gripper ?g) (at-robby ?r) (at ?b ?r) (free ?g)
               (carry ?o ?g))
  (:action move
    :parameters (?from ?to)
    :precondition (and (room ?from) (room ?to) (at-robby ?from))
    :effect (and (at-robby ?to) (not (at-robby ?from))))
  (:action pick
    :parameters (?obj ?room ?gripper)
    :precondition (and (ball ?obj) (room ?room) (gripper ?gripper) (at ?obj ?room)
                       (at-robby ?room) (free ?gripper))
    :effect (and (carry ?obj ?gripper) (not (at ?obj ?room)) (not (free ?gripper))))
  (:action drop
    :parameters (?obj ?room ?gripper)
    :precondition (and (ball ?obj) (room ?room) (gripper ?gripper) (carry ?obj ?gripper)
                       (at-robby ?room))
    :effect (and (at ?obj ?room) (free ?gripper) (not (carry ?obj ?gripper)))))
"""

GRIPPER_PROBLEM = """
(define (problem gripper-4)  ; four balls, two grippers
  (:domain gripper-strips)
  (:objects rooma roomb ball1 ball2 ball3 ball4 left right)
  (:init (room rooma) (room roomb) (ball ball1) (ball ball2) (ball ball3) (ball ball4)
         (gripper left) (gripper right) (at-robby rooma) (free left) (free right)
         (at ball1 rooma) (at ball2 rooma) (at ball3 rooma) (at ball4 rooma))
  (:goal (and (at ball1 roomb) (at ball2 roomb) (at ball3 roomb) (at ball4 roomb))))
"""

BLOCKS_DOMAIN = """
(define (domain blocks)
  (:requirements :strips)
  (:predicates (on ?x ?y) (ontable ?x) (clear ?x) (handempty) (holding ?x))
  (:action pick-up
    :parameters (?x)
    :precondition (and (clear ?x) (ontable ?x) (handempty))
    :effect (and (not (ontable ?x)) (not (clear ?x)) (not (handempty)) (holding ?x)))
  (:action put-down
    :parameters (?x)
    :precondition (holding ?x)
    :effect (and (not (holding ?x)) (clear ?x) (handempty) (ontable ?x)))
  (:action stack
    :parameters (?x ?y)
    :precondition (and (holding ?x) (clear ?y))
    :effect (and (not (holding ?x)) (not (clear ?y)) (clear ?x) (handempty) (on ?x ?y)))
  (:action unstack
    :parameters (?x ?y)
    :precondition (and (on ?x ?y) (clear ?x) (handempty))
    :effect (and (holding ?x) (clear ?y) (not (clear ?x)) (not (handempty))
                 (not (on ?x ?y)))))
"""


def blocks_problem(init_towers, goal_towers, name="blocks") -> str:
    """Blocksworld problem text; towers are lists of blocks listed bottom to top."""
    blocks = sorted(b for tower in init_towers for b in tower)
    init = ["(handempty)"]
    for tower in init_towers:
        init.append(f"(ontable {tower[0]})")
        init += [f"(on {top} {below})" for below, top in zip(tower, tower[1:])]
        init.append(f"(clear {tower[-1]})")
    goal = []
    for tower in goal_towers:
        goal.append(f"(ontable {tower[0]})")
        goal += [f"(on {top} {below})" for below, top in zip(tower, tower[1:])]
    return (f"(define (problem {name}) (:domain blocks) (:objects {' '.join(blocks)})\n"
            f"  (:init {' '.join(init)})\n  (:goal (and {' '.join(goal)})))")


BLOCKS_PROBLEM = blocks_problem([["c", "a"], ["b"], ["e", "d"]], [["a", "b", "c", "d", "e"]],
                                "blocks-5")

LOGISTICS_DOMAIN = """
(define (domain logistics-typed)
  (:requirements :strips :typing)
  (:types truck airplane - vehicle
          package vehicle - physobj
          airport - location
          city location physobj - object)
  (:predicates (in-city ?loc - location ?city - city) (at ?obj - physobj ?loc - location)
               (in ?pkg - package ?veh - vehicle))
  (:action load-vehicle
    :parameters (?pkg - package ?veh - vehicle ?loc - location)
    :precondition (and (at ?pkg ?loc) (at ?veh ?loc))
    :effect (and (not (at ?pkg ?loc)) (in ?pkg ?veh)))
  (:action unload-vehicle
    :parameters (?pkg - package ?veh - vehicle ?loc - location)
    :precondition (and (in ?pkg ?veh) (at ?veh ?loc))
    :effect (and (not (in ?pkg ?veh)) (at ?pkg ?loc)))
  (:action drive-truck
    :parameters (?truck - truck ?from ?to - location ?city - city)
    :precondition (and (at ?truck ?from) (in-city ?from ?city) (in-city ?to ?city))
    :effect (and (not (at ?truck ?from)) (at ?truck ?to)))
  (:action fly-airplane
    :parameters (?plane - airplane ?from ?to - airport)
    :precondition (at ?plane ?from)
    :effect (and (not (at ?plane ?from)) (at ?plane ?to))))
"""

LOGISTICS_PROBLEM = """
(define (problem logistics-2-2)
  (:domain logistics-typed)
  (:objects plane - airplane
            truck1 truck2 - truck
            city1 city2 - city
            office1 office2 - location
            port1 port2 - airport
            pkg1 pkg2 - package)
  (:init (in-city office1 city1) (in-city port1 city1)
         (in-city office2 city2) (in-city port2 city2)
         (at plane port1) (at truck1 office1) (at truck2 port2)
         (at pkg1 office1) (at pkg2 port2))
  (:goal (and (at pkg1 office2) (at pkg2 office1))))
"""

# Typed hierarchy three levels deep; actions take supertypes and the goal needs subtypes.
WORKSHOP_DOMAIN = """
(define (domain workshop)
  (:requirements :strips :typing)
  (:types station - place
          shelf bench - station
          tool part - item
          screwdriver wrench - tool
          item place robot - object)
  (:predicates (robot-at ?r - robot ?p - place) (item-at ?i - item ?p - place)
               (holding ?r - robot ?i - item) (hand-free ?r - robot)
               (fastened ?p - part) (link ?a ?b - place))
  (:action go
    :parameters (?r - robot ?a ?b - place)
    :precondition (and (robot-at ?r ?a) (link ?a ?b))
    :effect (and (robot-at ?r ?b) (not (robot-at ?r ?a))))
  (:action grab
    :parameters (?r - robot ?i - item ?p - station)
    :precondition (and (robot-at ?r ?p) (item-at ?i ?p) (hand-free ?r))
    :effect (and (holding ?r ?i) (not (item-at ?i ?p)) (not (hand-free ?r))))
  (:action release
    :parameters (?r - robot ?i - item ?p - station)
    :precondition (and (robot-at ?r ?p) (holding ?r ?i))
    :effect (and (item-at ?i ?p) (hand-free ?r) (not (holding ?r ?i))))
  (:action fasten
    :parameters (?r - robot ?t - screwdriver ?x - part ?b - bench)
    :precondition (and (robot-at ?r ?b) (holding ?r ?t) (item-at ?x ?b))
    :effect (fastened ?x)))
"""

WORKSHOP_PROBLEM = """
(define (problem workshop-1)
  (:domain workshop)
  (:objects r1 - robot hall - place rack - shelf table - bench
            sd - screwdriver wr - wrench plate bracket - part)
  (:init (robot-at r1 hall) (hand-free r1)
         (link hall rack) (link rack hall) (link hall table) (link table hall)
         (item-at wr rack) (item-at sd rack) (item-at plate table) (item-at bracket rack))
  (:goal (and (fastened plate) (fastened bracket) (item-at wr table))))
"""

# Towers of Hanoi with pegs as domain constants, "covered" tested negatively, and equality.
HANOI_DOMAIN = """
(define (domain hanoi-neg)
  (:requirements :strips :typing :negative-preconditions :equality)
  (:types disc peg - place)
  (:constants left middle right - peg)
  (:predicates (on ?d - disc ?x - place) (covered ?x - place) (smaller ?d - disc ?x - place))
  (:action move
    :parameters (?d - disc ?from ?to - place)
    :precondition (and (on ?d ?from) (not (covered ?d)) (not (covered ?to))
                       (smaller ?d ?to) (not (= ?from ?to)) (not (= ?d ?to)))
    :effect (and (not (on ?d ?from)) (not (covered ?from)) (on ?d ?to) (covered ?to))))
"""


def hanoi_problem(n: int) -> str:
    discs = [f"d{i}" for i in range(1, n + 1)]  # d1 smallest
    smaller = [f"(smaller {d} {p})" for d in discs for p in ("left", "middle", "right")]
    smaller += [f"(smaller {a} {b})" for i, a in enumerate(discs) for b in discs[i + 1:]]
    stack = discs[::-1]  # largest at the bottom of the left peg
    on = [f"(on {stack[0]} left)"] + [f"(on {t} {b})" for b, t in zip(stack, stack[1:])]
    covered = ["(covered left)"] + [f"(covered {d})" for d in stack[:-1]]
    goal = [f"(on {stack[0]} right)"] + [f"(on {t} {b})" for b, t in zip(stack, stack[1:])]
    return (f"(define (problem hanoi-{n}) (:domain hanoi-neg)\n"
            f"  (:objects {' '.join(discs)} - disc)\n"
            f"  (:init {' '.join(smaller + on + covered)})\n"
            f"  (:goal (and {' '.join(goal)})))")


HANOI_PROBLEM = hanoi_problem(3)

# Visit every cell of a grid, entering each cell at most once (negative precondition), with an
# `either`-typed parameter.
VISIT_DOMAIN = """
(define (domain visit-once)
  (:requirements :strips :typing :negative-preconditions :equality)
  (:types room corridor - object)
  (:predicates (at ?c - (either room corridor)) (visited ?c - (either room corridor))
               (door ?a ?b - (either room corridor)))
  (:action step
    :parameters (?from ?to - (either room corridor))
    :precondition (and (at ?from) (door ?from ?to) (not (visited ?to)) (not (= ?from ?to)))
    :effect (and (at ?to) (visited ?to) (not (at ?from)))))
"""


def visit_problem(cells: list[str], doors: list[tuple[str, str]], start: str) -> str:
    door_facts = " ".join(f"(door {a} {b}) (door {b} {a})" for a, b in doors)
    typed = " ".join(f"{c} - {'corridor' if c.startswith('h') else 'room'}" for c in cells)
    goal = " ".join(f"(visited {c})" for c in cells)
    return (f"(define (problem visit) (:domain visit-once) (:objects {typed})\n"
            f"  (:init (at {start}) (visited {start}) {door_facts})\n"
            f"  (:goal (and {goal})))")


# 2x3 grid of rooms around a corridor cell h1 in the middle of one row.
VISIT_PROBLEM = visit_problem(
    ["r1", "h1", "r3", "r4", "r5", "r6"],
    [("r1", "h1"), ("h1", "r3"), ("r4", "r5"), ("r5", "r6"), ("r1", "r4"), ("h1", "r5"),
     ("r3", "r6")], "r1")

# Small version of the project's skill domain: skills as actions, robot and table as constants.
ROBOT_DOMAIN = """
(define (domain skills)
  (:requirements :strips :typing :negative-preconditions :equality)
  (:types manipulatable container - thing
          peg - manipulatable
          thing location arm - object)
  (:constants arm1 - arm table - location)
  (:predicates (arm-at ?a - arm ?l - location) (thing-at ?t - thing ?l - location)
               (holding ?a - arm ?t - manipulatable) (busy ?a - arm)
               (inserted ?p - peg ?c - container) (fits ?p - peg ?c - container))
  (:action go-to
    :parameters (?a - arm ?from ?to - location)
    :precondition (and (arm-at ?a ?from) (not (= ?from ?to)))
    :effect (and (arm-at ?a ?to) (not (arm-at ?a ?from))))
  (:action pick
    :parameters (?a - arm ?t - manipulatable ?l - location)
    :precondition (and (arm-at ?a ?l) (thing-at ?t ?l) (not (busy ?a)))
    :effect (and (holding ?a ?t) (busy ?a) (not (thing-at ?t ?l))))
  (:action place
    :parameters (?a - arm ?t - manipulatable ?l - location)
    :precondition (and (arm-at ?a ?l) (holding ?a ?t))
    :effect (and (thing-at ?t ?l) (not (holding ?a ?t)) (not (busy ?a))))
  (:action push
    :parameters (?a - arm ?t - manipulatable ?from ?to - location)
    :precondition (and (arm-at ?a ?from) (thing-at ?t ?from) (not (busy ?a))
                       (not (= ?from ?to)) (not (= ?to table)))
    :effect (and (thing-at ?t ?to) (arm-at ?a ?to) (not (thing-at ?t ?from))
                 (not (arm-at ?a ?from))))
  (:action insert
    :parameters (?a - arm ?p - peg ?c - container ?l - location)
    :precondition (and (arm-at ?a ?l) (holding ?a ?p) (thing-at ?c ?l) (fits ?p ?c))
    :effect (and (inserted ?p ?c) (not (holding ?a ?p)) (not (busy ?a)))))
"""

ROBOT_PROBLEM = """
(define (problem peg-in-box)
  (:domain skills)
  (:objects peg1 peg2 - peg box1 - container home shelf station - location)
  (:init (arm-at arm1 home) (thing-at peg1 shelf) (thing-at peg2 shelf) (thing-at box1 table)
         (fits peg1 box1))
  (:goal (and (inserted peg1 box1) (thing-at peg2 station))))
"""

# Fast Downward rejects `either`; every object here is a room or a corridor, so `object` is an
# equivalent reading for the oracle.
VISIT_DOMAIN_WITHOUT_EITHER = VISIT_DOMAIN.replace("(either room corridor)", "object")


class Case(NamedTuple):
    domain: str
    problem: str
    oracle: str  # "pyperplan" or "fd"
    oracle_domain: str  # what the oracle reads (the domain itself unless it cannot)


CASES = {
    "gripper": Case(GRIPPER_DOMAIN, GRIPPER_PROBLEM, "pyperplan", GRIPPER_DOMAIN),
    "blocksworld": Case(BLOCKS_DOMAIN, BLOCKS_PROBLEM, "pyperplan", BLOCKS_DOMAIN),
    "logistics": Case(LOGISTICS_DOMAIN, LOGISTICS_PROBLEM, "pyperplan", LOGISTICS_DOMAIN),
    "workshop-typed": Case(WORKSHOP_DOMAIN, WORKSHOP_PROBLEM, "pyperplan", WORKSHOP_DOMAIN),
    "hanoi-neg-eq": Case(HANOI_DOMAIN, HANOI_PROBLEM, "fd", HANOI_DOMAIN),
    "visit-either": Case(VISIT_DOMAIN, VISIT_PROBLEM, "fd", VISIT_DOMAIN_WITHOUT_EITHER),
    "robot-skills": Case(ROBOT_DOMAIN, ROBOT_PROBLEM, "fd", ROBOT_DOMAIN),
}


# ---- independent oracles -----------------------------------------------------------------


def pyperplan_plan(domain: str, problem: str, heuristic: str = "hmax") -> list[str] | None:
    """Optimal plan from pyperplan's A* (h_max, LM-cut or blind), as lower-case ground
    actions."""
    from pyperplan.heuristics.blind import BlindHeuristic
    from pyperplan.heuristics.lm_cut import LmCutHeuristic
    from pyperplan.heuristics.relaxation import hMaxHeuristic
    from pyperplan.planner import search_plan
    from pyperplan.search import astar_search

    heuristic_class = {"hmax": hMaxHeuristic, "blind": BlindHeuristic,
                       "lmcut": LmCutHeuristic}[heuristic]
    with tempfile.TemporaryDirectory() as tmp:
        dfile, pfile = os.path.join(tmp, "domain.pddl"), os.path.join(tmp, "problem.pddl")
        with open(dfile, "w") as f:
            f.write(domain)
        with open(pfile, "w") as f:
            f.write(problem)
        plan = search_plan(dfile, pfile, astar_search, heuristic_class)
    return None if plan is None else [op.name.lower() for op in plan]


def pyperplan_task(domain: str, problem: str):
    """pyperplan's ground task (for applying plans with pyperplan's own semantics)."""
    from pyperplan.planner import _ground, _parse

    with tempfile.TemporaryDirectory() as tmp:
        dfile, pfile = os.path.join(tmp, "domain.pddl"), os.path.join(tmp, "problem.pddl")
        with open(dfile, "w") as f:
            f.write(domain)
        with open(pfile, "w") as f:
            f.write(problem)
        # keep every operator: a plan step pyperplan would prune must still be found
        return _ground(_parse(dfile, pfile), remove_irrelevant_operators=False)


def fast_downward_script() -> str:
    package_dir = find_spec("up_fast_downward").submodule_search_locations[0]
    return os.path.join(package_dir, "downward", "fast-downward.py")


def fast_downward_plan(domain: str, problem: str) -> list[str] | None:
    """Optimal plan from Fast Downward (seq-opt-lmcut); None when it proves unsolvability."""
    with tempfile.TemporaryDirectory() as tmp:
        for name, text in (("domain.pddl", domain), ("problem.pddl", problem)):
            with open(os.path.join(tmp, name), "w") as f:
                f.write(text)
        run = subprocess.run([sys.executable, fast_downward_script(), "--alias",
                              "seq-opt-lmcut", "domain.pddl", "problem.pddl"],
                             cwd=tmp, capture_output=True, text=True, timeout=120)
        plan_file = os.path.join(tmp, "sas_plan")
        if not os.path.exists(plan_file):
            # exit code 11/12: search (or translator) proved the task unsolvable
            assert run.returncode in (11, 12), run.stdout[-2000:] + run.stderr[-2000:]
            return None
        with open(plan_file) as f:
            # FD writes "(name a b)" but "(name )" for actions without parameters
            return ["(" + " ".join(line.strip().strip("()").lower().split()) + ")"
                    for line in f if not line.startswith(";")]


def oracle_plan(domain: str, problem: str, oracle: str) -> list[str] | None:
    return (pyperplan_plan if oracle == "pyperplan" else fast_downward_plan)(domain, problem)
