"""The third task: sliding a block along a fence into a slot, declared in
assets/scenarios/slide.yaml and drawn in assets/slide.xml, with no Python of its own. References:
the MJCF read by MuJoCo itself, MJX's own model check, and native MuJoCo rollouts."""

from __future__ import annotations

import re
from pathlib import Path

import jax
import mujoco
import numpy as np
import pytest

from mjxskill import build_model, load_scenario
from mjxskill.engine.native import NativeRollout
from mjxskill.task import plan_task

PACKAGE = Path(__file__).resolve().parents[2] / "mjxskill"
# The pusher centred on the block, turned 2 degrees clockwise, pressing 5 N toward the fence, the
# push ending 5.5 cm behind the seated block (found by hand on the native engine).
STEERING_PUSH = np.array([0.0, 0.0, -0.055, -2.0, 5.0])


@pytest.fixture(scope="module")
def slide():
    scn = load_scenario("slide")
    return scn, plan_task(scn)


def test_the_task_is_yaml_and_mjcf_only(slide):
    scn, task = slide
    assert [step.skill for step in task.steps] == ["GoToLinear", "FenceSlide"]
    assert Path(scn.scene).name == "slide.xml" and Path(scn.source).name == "slide.yaml"
    assert "FenceSlide" in scn.skills and "GoToLinear" in scn.skills  # its own, and the library's
    # nothing under mjxskill/ knows this task: not its name, its skill, its objects or predicate
    pattern = re.compile(r"\b(slide\.yaml|slide\.xml|FenceSlide|slidable|Block-1|Slot-1)\b")
    found = [f"{p}:{i}" for p in PACKAGE.rglob("*.py") for i, line in enumerate(p.read_text().splitlines(), 1)
             if pattern.search(line)]
    assert found == []
    assert task.parameter_names == ("FenceSlide.offset_x_start", "FenceSlide.offset_x_end",
                                    "FenceSlide.offset_y_end", "FenceSlide.yaw", "FenceSlide.press")


def test_the_yaml_and_the_mjcf_agree_and_mjx_takes_the_model(slide):
    scn, _ = slide
    built, raw = build_model(scn), mujoco.MjModel.from_xml_path(scn.scene)
    block = built.body("block").id
    assert built.body_mass[block] == pytest.approx(0.6)
    np.testing.assert_allclose(built.geom_size[built.geom("block").id], [0.04, 0.025, 0.02])
    for field in ("body_mass", "body_ipos", "body_pos", "geom_size", "pair_friction"):
        np.testing.assert_allclose(getattr(built, field), getattr(raw, field), atol=2e-6, err_msg=field)
    pairs = {built.geom(int(g)).name for g in np.concatenate([built.pair_geom1, built.pair_geom2])}
    assert pairs == {"tool_geom", "block", "table", "fence", "stop", "lip"}
    from mujoco import mjx

    mjx.put_model(built)  # raises for a contact pair MJX has no collision function for


def test_a_pusher_turned_toward_the_fence_seats_the_block_from_every_start(slide):
    # The pusher's face sets the block's yaw. Turned 2 degrees clockwise it steers the block into
    # the fence, which guides it past the lip into the slot, from every start configuration;
    # square (the planner's defaults, the push ending at the slot's centre: into the stop) the
    # arm's tracking leaves it turned either way, and it mostly jams. So the task has something
    # to learn.
    scn, task = slide
    native = NativeRollout(scn, task, worlds=8)
    worlds = native.worlds_per_config(jax.random.key(1), 2)  # 2 worlds from each of the 4 starts
    params = np.stack([STEERING_PUSH, task.defaults])
    out = native.run_worlds(params, jax.tree.map(lambda a: np.broadcast_to(a, (2,) + a.shape), worlds))
    success = np.asarray(out.success)
    assert success[0].sum() >= 7, out.metrics["orientation_error_deg"]
    assert success[1].sum() <= 2, out.metrics["orientation_error_deg"]
    # the steered push also touches less: the measured force, not the commanded one, says so
    peak = np.asarray(out.metrics["peak_contact_force"]).mean(axis=1)
    assert peak[0] < peak[1]
