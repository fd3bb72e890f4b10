"""The paper's round peg (radius 15 mm, in a hole of 1.5 mm larger radius) inserted on the native
engine, the CPU engine and the compiled one's reference (MJX collides the same mesh and boxes,
but compiling the peg episode costs minutes here: tests/engine/mjx/test_rollout.py runs MJX on peg_square)."""

import jax
import numpy as np
import pytest

import mjxskill  # noqa: F401
from mjxskill import load_scenario
from mjxskill.engine.native import NativeRollout
from mjxskill.task import plan_task
from rollout_inputs import params_of, placed_worlds

SPIRAL = {"PegInsertion.force": -5.0, "PegInsertion.radius": 0.012, "PegInsertion.path_velocity": 0.03}


@pytest.fixture(scope="module")
def peg():
    scn = load_scenario("peg")
    engine = NativeRollout(scn, plan_task(scn), worlds=2, episode_seconds=10.0)
    yield scn, engine
    engine.close()


def test_pressing_down_needs_an_aligned_hole_and_the_spiral_finds_a_5mm_offset_one(peg):
    # The box where the world model says, and 5 mm off (4 mm along x, -3 mm along y): more than
    # the clearance plus the peg's radius can tip over, so only a search finds the hole.
    scn, engine = peg
    worlds = placed_worlds(engine, [(0, {"BoxWithHole-1": (0.0, 0.0)}, None),
                                    (0, {"BoxWithHole-1": (0.004, -0.003)}, None)])
    worlds = jax.tree.map(lambda x: np.stack([np.asarray(x)] * 2), worlds)
    out = engine.run_worlds(params_of(engine.task, {}, SPIRAL).astype(float), worlds)
    success = np.asarray(out.success)
    assert success.tolist() == [[True, False], [True, True]]
    depth = np.asarray(out.metrics["insertion_depth"])
    hole = scn.objects["BoxWithHole-1"].extra
    # inserted pegs reach the hole's bottom; the one left on the rim did not enter at all
    np.testing.assert_allclose(depth[success], hole["hole_depth"], atol=1e-3)
    assert abs(depth[0, 1]) < 1e-3
    # in the hole, the peg's axis is within the clearance of the hole's (the drawn polygons add
    # at most 0.3 mm); on the rim, farther than that
    position_error = np.asarray(out.metrics["position_error"])
    assert np.all(position_error[success] <= hole["hole_clearance"] + 3e-4)
    assert position_error[0, 1] > 0.004
    np.testing.assert_array_equal(np.asarray(out.metrics["bt_success"]), success)
    assert not np.asarray(out.metrics["diverged"]).any()
