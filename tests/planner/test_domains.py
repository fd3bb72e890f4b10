"""The planner tests' classic PDDL cases (tests/helpers/planner_domains.py) are readable by
their oracles: pyperplan's cases stay inside pyperplan's language, so a case it would misread
cannot pass silently."""

import pytest

from planner_domains import CASES, pyperplan_task


@pytest.mark.parametrize("name", [n for n, c in CASES.items() if c[2] == "pyperplan"])
def test_pyperplan_cases_have_no_negation_or_equality(name):
    # pyperplan would silently misread these constructs, so they must be FD cases.
    domain, problem = CASES[name].domain, CASES[name].problem
    assert "(not (=" not in domain and ":negative-preconditions" not in domain
    assert "either" not in domain
    task = pyperplan_task(domain, problem)
    assert task.operators, "pyperplan grounded no operators: the case text is broken"
