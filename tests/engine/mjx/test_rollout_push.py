"""The compiled push rollout can succeed, and its difficulty is the paper's.

Pushing the prism 0.43 m and turning it by 26 degrees open-loop lands it within 1 cm and 5 deg of
the goal only because the goal is a corner (fence + stop, assets/push.xml) and the push drives the
prism into it. The planner's zero offsets put the pusher on top of the prism and never move it; a
straight push from behind its left part (found by a hand search with the native baseline, see
the issue's closing note) succeeds across the randomization: start configurations, object and
goal offsets of 1 sd in opposite directions (where SkiREIL's clip stopped them; the paper's
Gaussian goes beyond), both friction bounds.
"""

import jax
import jax.numpy as jnp
import numpy as np

from rollout_inputs import params_of, placed_worlds

HAND_FOUND = {"Push.offset_x_start": -0.05, "Push.offset_y_start": -0.15, "Push.offset_x_goal": 0.07, "Push.offset_y_goal": -0.10}


def extreme_worlds(scn, rollout, cases):
    """Worlds (W,) from (start configuration, object sign, goal sign, friction) cases: the object
    and goal offsets at sign * sigma (1 sd)."""
    sigma = scn.randomization.xy_sigma
    return placed_worlds(rollout, [
        (config, {"ObjectToBePushed-1": np.multiply(obj_sign, sigma["ObjectToBePushed-1"]),
                  "ObjectGoalPose-1": np.multiply(goal_sign, sigma["ObjectGoalPose-1"])}, friction)
        for config, obj_sign, goal_sign, friction in cases
    ])


def test_planner_offsets_fail_and_a_straight_push_into_the_corner_succeeds(push_rollout):
    scn, rollout = push_rollout
    params = params_of(rollout, {}, HAND_FOUND)
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
