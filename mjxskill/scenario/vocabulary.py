"""The world model's vocabularies, each declared once: reward kinds, shapes, success tests.

The loader (``mjxskill.scenario``) reads what a YAML may and must give from these tables; each
engine keeps one implementation per entry (rewards: ``mjxskill.engine.mjx.rewards`` and
``mjxskill.engine.native.rewards``; success tests: ``mjxskill.engine.mjx.success`` and
``mjxskill.engine.native.success``; shapes: ``mjxskill.sim.shapes``), and tests check that every
registry names exactly its table.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

from mjxskill.scenario.domain import Domain


REQUIRED = None  # a reward constant without a default: the YAML must give it


@dataclass(frozen=True)
class RewardKind:
    """One entry of the reward vocabulary.

    constants: name -> default (``REQUIRED``: the YAML must give it); the loader rejects any
    other constant. needs: the reward's own keys the kind reads ("object", "target").
    domains: name -> the constant's ``Domain`` (``CONSTANT_DOMAINS`` where the kind gives none):
    the values the reward's formula can take, checked when the scenario loads.
    """

    constants: Mapping[str, float | None]
    needs: tuple[str, ...] = ()
    domains: Mapping[str, Domain] = field(default_factory=lambda: MappingProxyType({}))

    def domain(self, constant: str) -> Domain:
        return self.domains.get(constant) or CONSTANT_DOMAINS[constant]


# The reward constants' domains (``Reward`` gives the formulas). sigma_w divides, squared (0
# divided by zero after the run directory existed; at 0.1 mm the exponential is already a step
# 1e-4 m wide). The weights multiply a distance (m) or an angle (rad), d_o shifts one; cap
# bounds a force.
CONSTANT_DOMAINS: Mapping[str, Domain] = MappingProxyType({
    "value": Domain(-1e6, 1e6, why="the reward per tick; an objective sums it over every tick"),
    "w": Domain(1e-6, 1e6, why="1 / (w (d + d_o)) divides by it"),
    "d_o": Domain(0.0, 100.0, why="an offset of a distance (m) or an angle (rad)"),
    "sigma_w": Domain(1e-4, 100.0, why="exp(-(d + d_o) / (2 sigma_w^2)) divides by its square"),
    "position_weight": Domain(0.0, 1e6, why="weights a distance"),
    "orientation_weight": Domain(0.0, 1e6, why="weights an angle"),
    "cap": Domain(0.0, 1e6, exclusive_minimum=True, unit="N", why="the largest force counted"),
})


# The reward vocabulary, read by the loader (what a YAML may and must give), the compiled
# rewards (mjxskill.engine.mjx.rewards) and the native ones (mjxskill.engine.native.rewards): one table, so
# the three cannot disagree about a kind, a constant or a default. Meanings: ``Reward``.
REWARD_KINDS: Mapping[str, RewardKind] = MappingProxyType(
    {
        "task_completion": RewardKind(MappingProxyType({"value": REQUIRED})),
        # d_o > 0: at d = 0 the reward 1 / (w d) is infinite (and its worst value, with a
        # negative weight, too)
        "ee_distance_to_box": RewardKind(MappingProxyType({"w": REQUIRED, "d_o": REQUIRED}), ("target",),
                                         MappingProxyType({"d_o": Domain(1e-6, 100.0, unit="m", why=(
                                             "1 / (w (d + d_o)) is infinite at d = 0 when d_o is 0"))})),
        "applied_wrench": RewardKind(MappingProxyType({"cap": 100.0})),
        "contact_force": RewardKind(MappingProxyType({"cap": 100.0})),
        "exp_ee_to_goal": RewardKind(MappingProxyType({"sigma_w": REQUIRED, "d_o": REQUIRED}), ("target",)),
        "exp_ee_to_reference": RewardKind(MappingProxyType({"sigma_w": REQUIRED, "d_o": REQUIRED})),
        "object_pose_divergence": RewardKind(
            MappingProxyType(
                {"sigma_w": REQUIRED, "d_o": REQUIRED, "position_weight": REQUIRED, "orientation_weight": REQUIRED}
            ),
            ("object", "target"),
        ),
    }
)


@dataclass(frozen=True)
class ShapeKind:
    """One entry of the shape vocabulary: how many numbers ``size`` has (what they are: the
    comment of ``SHAPES``) and the ``extra`` constants the shape takes (all required)."""

    size: int
    extra: tuple[str, ...] = ()


# The shapes the world model knows, read by the loader (size and extra keys) and by
# mjxskill.sim.shapes (inertia and geometry, one registry with exactly these names).
# pose: no body, size []. box: [x, y, z] edge lengths. right_triangle_prism: legs [x, y] along
# the body axes and height z, body origin at the triangle's centroid at half height, the right
# angle at (-x/3, -y/3). cylinder: [radius, height], axis along the body's z. box_with_hole:
# outer [x, y, z], origin at the bottom centre, a square hole centred and open at the top,
# hole_depth deep and hole_clearance wider on each side than the (box) item the robot holds.
# box_with_round_hole: the same with a round hole whose radius is hole_clearance larger than
# that of the (cylinder) item the robot holds.
SHAPES: Mapping[str, ShapeKind] = MappingProxyType(
    {
        "pose": ShapeKind(0),
        "box": ShapeKind(3),
        "right_triangle_prism": ShapeKind(3),
        "cylinder": ShapeKind(2),
        "box_with_hole": ShapeKind(3, ("hole_clearance", "hole_depth")),
        "box_with_round_hole": ShapeKind(3, ("hole_clearance", "hole_depth")),
    }
)


# The success tests a scenario can select (``success.kind``): kind -> (required keys, optional
# keys) besides kind, object and target. Both engines keep one test per kind
# (mjxskill.engine.mjx.success, mjxskill.engine.native.success) and a test checks they name exactly these.
SUCCESS_KINDS: Mapping[str, tuple[tuple[str, ...], tuple[str, ...]]] = MappingProxyType(
    {
        "object_at_pose": (("position_tolerance", "orientation_tolerance_deg"), ()),
        "inserted": (("depth",), ()),
        "object_in_region": (("region_size",), ("region_center", "orientation_tolerance_deg")),
    }
)
