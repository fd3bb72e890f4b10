"""One table per vocabulary: the leaf primitives and the reward kinds are declared once, and the
loader and both engines follow that declaration."""

import numpy as np
import pytest

from mjxskill.ebt.primitives import PRIMITIVES
from mjxskill.engine.common.arrays import HOST, JAX
from mjxskill.engine.common.rewards import build_terms
from mjxskill.errors import ScenarioError
from mjxskill.engine.native.leaves import LEAF_PROGRAMS as NATIVE_LEAVES
from mjxskill.engine.mjx.leaves import LEAF_PROGRAMS as COMPILED_LEAVES
from mjxskill.scenario import load_scenario
from mjxskill.scenario.vocabulary import REQUIRED, REWARD_KINDS
from scenario_texts import shipped_text


def test_both_engines_implement_exactly_the_ebt_primitives():
    assert tuple(COMPILED_LEAVES) == PRIMITIVES
    assert tuple(NATIVE_LEAVES) == PRIMITIVES


def test_reward_constants_follow_the_table(tmp_path):
    scn = load_scenario("peg")
    for reward in scn.rewards:
        spec = REWARD_KINDS[reward.kind]
        assert set(reward.constants) == set(spec.constants)  # every constant, defaults filled in
        for key, default in spec.constants.items():
            if default is not REQUIRED and key not in reward.constants:
                assert reward.constant(key) == default


def test_the_loader_accepts_cap_and_rejects_an_unknown_constant(tmp_path):
    text = shipped_text("push")
    anchor = "  - {name: reference_tracking,"
    assert text.count(anchor) == 1
    extra = "  - {name: commanded_force, kind: applied_wrench, objective: applied_force, weight: -0.1, constants: {cap: 20.0}}\n"
    path = tmp_path / "push.yaml"
    path.write_text(text.replace(anchor, extra + anchor))
    loaded = load_scenario(path)
    reward = next(r for r in loaded.rewards if r.name == "commanded_force")
    assert reward.constant("cap") == 20.0
    from mjxskill.engine.common.bindings import bind_scene, referenced_objects
    from mjxskill.sim.model import build_model

    bindings = bind_scene(loaded, build_model(loaded), referenced_objects(loaded, []))
    compiled = next(t for t in build_terms(loaded, bindings.slot_of, JAX) if t.name == "commanded_force")
    native = next(t for t in build_terms(loaded, bindings.slot_of, HOST) if t.name == "commanded_force")
    assert compiled.worst_raw == native.worst_raw == 20.0  # the cap is what a diverged world is charged
    path.write_text(text.replace(anchor, extra.replace("{cap: 20.0}", "{cap: 20.0, limit: 3}") + anchor))
    with pytest.raises(ScenarioError, match=r"rewards\[\d+\]\.constants\.limit \(line \d+\): unknown key 'limit'"):
        load_scenario(path)
    path.write_text(text.replace(anchor, extra.replace(", constants: {cap: 20.0}", "") + anchor))
    assert next(r for r in load_scenario(path).rewards if r.name == "commanded_force").constant("cap") == 100.0


def test_the_table_is_consistent():
    for kind, spec in REWARD_KINDS.items():
        assert all(v is REQUIRED or np.isfinite(v) for v in spec.constants.values()), kind
        assert set(spec.needs) <= {"object", "target"}, kind
