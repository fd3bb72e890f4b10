"""Benchmark: mjxskill.planner against pyperplan (A* with the same heuristic), end to end.

Times are wall-clock medians over repeats in this process, from PDDL text to plan (pyperplan
reads the same text from files: its parser only takes paths). Domains with negative
preconditions or equality are outside pyperplan's language; for those the table shows Fast
Downward (seq-opt-lmcut, a separate process, so it includes interpreter start-up) instead.

    python benchmarks/planner_vs_pyperplan.py [--repeats 3] [--heuristic hmax|lmcut|blind]
"""

from __future__ import annotations

import argparse
import logging
import os
import statistics
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "helpers"))

import mjxskill.planner as planner  # noqa: E402
from planner_domains import (  # noqa: E402
    BLOCKS_DOMAIN, CASES, GRIPPER_DOMAIN, HANOI_DOMAIN, VISIT_DOMAIN,
    VISIT_DOMAIN_WITHOUT_EITHER, blocks_problem, fast_downward_plan, hanoi_problem,
    pyperplan_plan, visit_problem)


def gripper_problem(n: int) -> str:
    balls = [f"ball{i}" for i in range(1, n + 1)]
    return (f"(define (problem gripper-{n}) (:domain gripper-strips)\n"
            f"  (:objects rooma roomb left right {' '.join(balls)})\n"
            "  (:init (room rooma) (room roomb) (gripper left) (gripper right) (at-robby rooma)"
            " (free left) (free right) " + " ".join(f"(ball {b}) (at {b} rooma)" for b in balls)
            + ")\n  (:goal (and " + " ".join(f"(at {b} roomb)" for b in balls) + ")))")


def grid_problem(rows: int, cols: int) -> str:
    cells = [f"r{i}{j}" for i in range(rows) for j in range(cols)]
    doors = [(f"r{i}{j}", f"r{i}{j + 1}") for i in range(rows) for j in range(cols - 1)]
    doors += [(f"r{i}{j}", f"r{i + 1}{j}") for i in range(rows - 1) for j in range(cols)]
    return visit_problem(cells, doors, cells[0])


def benchmarks():
    """(name, domain, problem, reference planner, domain text for the reference)."""
    yield from ((name, c.domain, c.problem, c.oracle, c.oracle_domain)
                for name, c in CASES.items())
    yield "gripper-6", GRIPPER_DOMAIN, gripper_problem(6), "pyperplan", GRIPPER_DOMAIN
    yield ("blocks-6", BLOCKS_DOMAIN,
           blocks_problem([["f", "a", "d"], ["b", "e"], ["c"]], [["a", "b", "c", "d", "e", "f"]]),
           "pyperplan", BLOCKS_DOMAIN)
    yield "hanoi-5", HANOI_DOMAIN, hanoi_problem(5), "fd", HANOI_DOMAIN
    yield "visit-grid-3x3", VISIT_DOMAIN, grid_problem(3, 3), "fd", VISIT_DOMAIN_WITHOUT_EITHER


def timed(fn, repeats):
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--heuristic", choices=["hmax", "lmcut", "blind"], default="hmax")
    args = parser.parse_args()
    logging.disable(logging.INFO)  # pyperplan logs every stage
    planner.solve(*next(benchmarks())[1:3])  # build pddl's lark parsers once (~0.2 s)

    header = (f"{'domain':16s} {'ours [s]':>9s} {'len':>4s} | {'reference':10s} {'time [s]':>9s}"
              f" {'len':>4s} | {'speed-up':>8s}")
    print(f"A* + {args.heuristic}, median of {args.repeats} runs")
    print(header)
    print("-" * len(header))
    for name, domain, problem, reference, reference_domain in benchmarks():
        ours_s, plan = timed(lambda: planner.solve(domain, problem, args.heuristic),
                             args.repeats)
        if reference == "pyperplan":
            ref_s, ref_plan = timed(
                lambda: pyperplan_plan(reference_domain, problem, args.heuristic), args.repeats)
            label = "pyperplan"
        else:
            ref_s, ref_plan = timed(lambda: fast_downward_plan(reference_domain, problem), 1)
            label = "FD (lmcut)"
        assert len(plan) == len(ref_plan), (name, plan, ref_plan)
        assert planner.validate(domain, problem, plan)
        print(f"{name:16s} {ours_s:9.3f} {len(plan):4d} | {label:10s} {ref_s:9.3f}"
              f" {len(ref_plan):4d} | {ref_s / ours_s:7.1f}x")


if __name__ == "__main__":
    main()
