"""The compiled push rollout can succeed, and its difficulty is the paper's.

Pushing the prism 0.43 m and turning it by 26 degrees open-loop lands it within 1 cm and 5 deg of
the goal only because the goal is a corner (fence + stop, assets/push.xml) and the push drives the
prism into it. The planner's zero offsets put the pusher on top of the prism and never move it; a
straight push from behind its left part (found by a hand search with the native baseline, see
the issue's closing note) succeeds at the extremes of the randomization: start configurations,
object and goal offsets at the +-1 sigma clip in opposite directions, both friction bounds.
"""

import jax
import jax.numpy as jnp
import numpy as np

from mjxskill.rollout import Worlds

HAND_FOUND = {"Push.offset_x_start": -0.05, "Push.offset_y_start": -0.15, "Push.offset_x_goal": 0.07, "Push.offset_y_goal": -0.10}


def params_of(scn, *rows) -> np.ndarray:
    out = np.tile(scn.parameter_defaults, (len(rows), 1)).astype(np.float32)
    for i, row in enumerate(rows):
        for name, value in row.items():
            out[i, scn.parameter_names.index(name)] = value
    return out


def extreme_worlds(scn, rollout, cases) -> Worlds:
    """Worlds (W,) from (start configuration, object offset, goal offset, friction) cases."""
    sigma = scn.randomization.xy_sigma
    slot_of = rollout.spec.bindings.slot_of
    worlds = []
    for config, obj_sign, goal_sign, friction in cases:
        base = jax.tree.map(lambda x: x[config], rollout.worlds_per_config(jax.random.key(0), 1))
        pos = np.asarray(base.object_pos, np.float32).copy()
        for name, sign in (("ObjectToBePushed-1", obj_sign), ("ObjectGoalPose-1", goal_sign)):
            slot = slot_of[name]
            pos[slot] = rollout.spec.bindings.slots[slot].position
            pos[slot, :2] += np.asarray(sign, np.float32) * sigma[name]
        worlds.append(base._replace(object_pos=jnp.asarray(pos), friction=jnp.float32(friction)))
    return jax.tree.map(lambda *xs: jnp.stack(xs), *worlds)


def test_planner_offsets_fail_and_a_straight_push_into_the_corner_succeeds(push_rollout):
    scn, rollout = push_rollout
    params = params_of(scn, {}, HAND_FOUND)
    cases = [
        [(0, (1, -1), (-1, 1), 0.25), (1, (-1, 1), (1, -1), 0.2)],
        [(2, (-1, -1), (1, 1), 0.2), (3, (1, 1), (-1, -1), 0.25)],
    ]
    for pair in cases:
        w = extreme_worlds(scn, rollout, pair)
        out = rollout.run_worlds(params, jax.tree.map(lambda x: jnp.stack([x, x]), w))
        success = np.asarray(out.success)
        pos_err = np.asarray(out.metrics["position_error"])
        assert success.tolist() == [[False, False], [True, True]], (success, pos_err)
        # The planner's pusher never moves the prism; the push lands it well inside 1 cm / 5 deg.
        assert np.all(pos_err[0] > 0.4)
        assert np.all(pos_err[1] < 0.006) and np.all(np.asarray(out.metrics["orientation_error_deg"])[1] < 2.5)
        assert not np.asarray(out.metrics["diverged"]).any()
        # Success objective: landing at the goal scores above staying put.
        objectives = np.asarray(out.objectives)
        assert objectives[1, 0] > objectives[0, 0]
