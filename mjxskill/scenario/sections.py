"""The task sections of a scenario YAML: rewards, success test, randomization, optimizer, pick."""

from __future__ import annotations

from typing import Any

from mjxskill.scenario.fields import Field
from mjxskill.errors import listing, quote
from mjxskill.scenario.domain import (ANGLE_TOLERANCE_DEG, CLIP_SIGMAS, DEPTH, FORCE, FRICTION_RANGE, POSITION, REGION_SIZE,
                                      SIGMA, TOLERANCE, WEIGHT)
from mjxskill.scenario.schema import (MAX_BATCH, MAX_BUDGET, MAX_REPEATS, MAX_SEED, MAX_WORLDS, MIN_N_INIT, Optimizer,
                                      PickBound, Randomization, Reward, Success, frozen_array, frozen_mapping)
from mjxskill.scenario.vocabulary import REQUIRED, REWARD_KINDS, SUCCESS_KINDS


def rewards(field: Field, objectives, object_names) -> tuple[Reward, ...]:
    """``rewards``: a list of terms, each of a kind of ``REWARD_KINDS`` with that kind's
    constants (defaults filled in) and the object keys it needs."""
    terms: list[Reward] = []
    used: set[str] = set()
    for item in field.seq():
        f = item.mapping(
            required=("name", "kind", "objective", "weight"), optional=("constants", "object", "target", "target_offset")
        )
        name = f["name"].string()
        if name in {r.name for r in terms}:
            f["name"].fail(f"duplicate reward name {quote(name)}")
        kind = f["kind"].string(choices=REWARD_KINDS)
        spec = REWARD_KINDS[kind]
        objective = f["objective"].string()
        if objective not in objectives:
            f["objective"].fail(f"unknown objective {quote(objective)} (objectives: {listing(objectives)})")
        used.add(objective)
        required = tuple(k for k, default in spec.constants.items() if default is REQUIRED)
        optional = tuple(k for k, default in spec.constants.items() if default is not REQUIRED)
        if "constants" in f:
            given = f["constants"].mapping(required=required, optional=optional)
        elif required:
            item.fail(f"missing key 'constants' ({kind} needs {listing(required)})")
        else:
            given = {}
        constants = {k: spec.constants[k] for k in optional} | {k: v.number(spec.domain(k)) for k, v in given.items()}
        for key in ("object", "target"):
            if key in f and f[key].string() not in object_names:
                f[key].fail(f"unknown object {quote(f[key].string())} (objects: {listing(sorted(object_names))})")
        missing = [key for key in spec.needs if key not in f]
        if missing:
            item.fail(f"{kind} needs {' and '.join(repr(k) for k in missing)} (an object name)")
        terms.append(
            Reward(
                name, kind, f["weight"].number(WEIGHT), objective, frozen_mapping(constants),
                f["object"].string() if "object" in f else None,
                f["target"].string() if "target" in f else None,
                frozen_array(f["target_offset"].vector(3, POSITION)) if "target_offset" in f else None,
            )
        )
    for objective in objectives:
        if objective not in used:
            field.fail(f"objective {quote(objective)} has no reward")
    return tuple(terms)


# the numbers of a success test (SUCCESS_KINDS), one domain each
_SUCCESS_DOMAINS = {"position_tolerance": TOLERANCE, "orientation_tolerance_deg": ANGLE_TOLERANCE_DEG, "depth": DEPTH}


def success(field: Field, objects) -> Success:
    """``success``: one test of ``SUCCESS_KINDS`` with its keys; ``objects``: name -> WorldObject."""
    f = field.mapping(required=("kind",), optional=tuple({k for r, o in SUCCESS_KINDS.values() for k in (*r, *o)})
                      + ("object", "target"))
    kind = f["kind"].string(choices=SUCCESS_KINDS)
    required, optional = SUCCESS_KINDS[kind]
    f = field.mapping(required=("kind", "object", "target", *required), optional=optional)
    for key in ("object", "target"):
        if f[key].string() not in objects:
            f[key].fail(f"unknown object {quote(f[key].string())} (objects: {listing(sorted(objects))})")
    values: dict[str, Any] = {}  # a number, or a region's vector (3,)
    for key in (*required, *optional):
        if key not in f:
            continue
        if key.startswith("region_"):
            values[key] = frozen_array(f[key].vector(3, REGION_SIZE if key == "region_size" else POSITION))
        else:
            values[key] = f[key].number(_SUCCESS_DOMAINS[key])
    if kind == "inserted" and objects[f["target"].string()].shape not in ("box_with_hole", "box_with_round_hole"):
        f["target"].fail(f"an insertion goes into the hole of a box_with_hole or a box_with_round_hole; "
                         f"{f['target'].string()} is a "
                         f"{objects[f['target'].string()].shape}")
    return Success(kind, f["object"].string(), f["target"].string(), **values)


def randomization(field: Field, object_names) -> Randomization:
    f = field.mapping(required=("n_worlds", "xy_sigma"), optional=("clip_sigmas", "friction_range"))
    sigma = {}
    for name, value in f["xy_sigma"].items():
        if name not in object_names:
            value.fail(f"unknown object {quote(name)} (objects: {listing(sorted(object_names))})")
        sigma[name] = value.number(SIGMA)
    clip = None if "clip_sigmas" not in f or f["clip_sigmas"].is_null() else f["clip_sigmas"].number(CLIP_SIGMAS)
    friction = None
    if "friction_range" in f and not f["friction_range"].is_null():
        low, high = f["friction_range"].vector(2, FRICTION_RANGE)
        if not 0 <= low <= high:
            f["friction_range"].fail(f"expected 0 <= low <= high, got [{low}, {high}]")
        friction = (low, high)
    return Randomization(frozen_mapping(sigma), clip, friction, f["n_worlds"].integer(minimum=1, maximum=MAX_WORLDS))


def optimizer(field: Field) -> Optimizer:
    f = field.mapping(required=("budget", "batch_size", "n_init", "seed", "repetitions"))
    opt = Optimizer(
        budget=f["budget"].integer(minimum=1, maximum=MAX_BUDGET),
        batch_size=f["batch_size"].integer(minimum=1, maximum=MAX_BATCH),
        n_init=f["n_init"].integer(minimum=MIN_N_INIT),
        seed=f["seed"].integer(minimum=0, maximum=MAX_SEED),
        repetitions=f["repetitions"].integer(minimum=1, maximum=MAX_REPEATS),
    )
    if opt.n_init > opt.budget:
        f["n_init"].fail(f"n_init {opt.n_init} exceeds the budget {opt.budget}")
    return opt




def pick(field: Field | None) -> PickBound | None:
    """``pick``: ``max_force`` (N, >= 0) and ``why`` (the reason for that number, which the
    report states beside it: a bound nobody can account for is not accepted)."""
    if field is None:
        return None
    f = field.mapping(required=("max_force", "why"))
    why = f["why"].scalar()
    if not isinstance(why, str) or not why.strip():
        f["why"].fail(f"expected the reason for the bound (text), got {quote(why)}")
    return PickBound(f["max_force"].number(FORCE), " ".join(why.split()))
