"""benchmarks/peg_approach.py's arguments and scenario copy (no rollout): a set is NAME=F,R,V
or a known name; ``--override`` updates the shipped ``skill_parameters`` entry by entry, field by
field, in a copy that loads."""

import argparse
import os
import sys

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "benchmarks"))
import peg_approach as pa


def test_sets_and_overrides_parse():
    assert pa.parse_set("op_b=-8,0.02,0.05") == ("op_b", [-8.0, 0.02, 0.05])
    assert pa.parse_set("pick0") == ("pick0", pa.SETS["pick0"])
    for bad in ("nope", "x=1,2", "x=a,b,c", "=1,2,3"):
        with pytest.raises(argparse.ArgumentTypeError):
            pa.parse_set(bad)
    assert pa.parse_override("GoToLinear.threshold=0.05") == ("GoToLinear.threshold", {"default": 0.05})
    assert pa.parse_override("PegInsertion.stiffness={default: [1, 2]}") == ("PegInsertion.stiffness", {"default": [1, 2]})
    with pytest.raises(argparse.ArgumentTypeError):
        pa.parse_override("threshold=0.05")


def defaults(scn, skill):
    return {p.name: p.default for p in scn.skills[skill].parameters}


def test_the_copy_keeps_the_shipped_entries_it_does_not_override():
    with pa.peg_scenario([]) as shipped:
        assert defaults(shipped, "GoToLinear")["threshold"] == 0.005  # peg.yaml's own skill_parameters
    stiffness = pa.parse_override("PegInsertion.stiffness={default: [1500, 1500, 0, 50, 50, 50]}")
    with pa.peg_scenario([stiffness]) as scn:
        assert defaults(scn, "GoToLinear")["threshold"] == 0.005
        assert tuple(defaults(scn, "PegInsertion")["stiffness"]) == (1500.0, 1500.0, 0.0, 50.0, 50.0, 50.0)
        assert os.path.isfile(scn.source)  # kept while in use: the native rollout hashes it
    assert not os.path.exists(scn.source)
    with pa.peg_scenario([pa.parse_override("GoToLinear.threshold=0.05")]) as scn:
        assert defaults(scn, "GoToLinear")["threshold"] == 0.05
