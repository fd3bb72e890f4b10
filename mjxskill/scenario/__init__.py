"""The digital twin: a scenario YAML read into an immutable, validated ``Scenario``.

Modules: ``fields`` (YAML nodes with file, key path and line for every error), ``schema`` (the
frozen dataclasses and the reward vocabulary), ``load`` (top level, PDDL vocabulary, robot,
objects), ``skills`` (skill library, operators' parameter sets), ``sections`` (rewards, success,
randomization, optimizer). Nothing here plans: ``mjxskill.task`` does.
"""

from mjxskill.errors import ScenarioError
from mjxskill.scenario.load import SCENARIO_DIR, available_scenarios, load_scenario, scenario_path
from mjxskill.scenario.schema import Scenario

__all__ = ["SCENARIO_DIR", "Scenario", "ScenarioError", "available_scenarios", "load_scenario", "scenario_path"]
