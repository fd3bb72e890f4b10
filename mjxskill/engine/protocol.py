"""The interface every physics engine gives: ``Rollout``, a ``typing.Protocol`` (both
``mjxskill.engine.mjx.compiled.MJXRollout`` and ``mjxskill.engine.native.rollout.NativeRollout``
satisfy it, and so do the native engine's wrappers, ``ProcessPoolRollout`` and ``RayRollout``;
``tests/engine/test_engines.py`` checks them), and ``RolloutBase``, what they compute the same way from
their task, scenario and episode setup.

    rollout = build_rollout(scn, task, "native", worlds=7)   # mjxskill.engine.build
    out = rollout(params, key)           # params (B, P) in rollout.parameter_names order
    out.objectives                       # (B, O), larger is better, mean over the W worlds
    out.success                          # (B, W) bool
    out.metrics                          # name -> (B, W) per-world values
    rollout.close()                      # worker processes, if any

The same key gives the same worlds on both engines (one sampler, ``mjxskill.engine.common.worlds``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, Self, runtime_checkable

import mujoco
import numpy as np

from mjxskill.engine.common.types import EpisodeResult, EpisodeSetup, RolloutOutput, TickRecord
from mjxskill.engine.common.worlds import Worlds
from mjxskill.scenario.schema import Scenario

if TYPE_CHECKING:  # pragma: no cover
    import jax

    from mjxskill.task import PlannedTask


@runtime_checkable
class Rollout(Protocol):
    """The episodes of one planned task, W randomized worlds per parameter set.

    scenario: the ``Scenario``; task: the ``mjxskill.task.PlannedTask`` it runs; worlds: W;
    setup: the engine-independent facts of an episode (``EpisodeSetup``); mj_model: the native
    model simulated (``mjxskill.sim.model.build_model``).
    """

    # Read-only properties here: an attribute, a frozen dataclass's field and a property all satisfy one.
    @property
    def scenario(self) -> Scenario: ...

    @property
    def task(self) -> PlannedTask: ...

    @property
    def worlds(self) -> int: ...

    @property
    def setup(self) -> EpisodeSetup: ...

    @property
    def mj_model(self) -> mujoco.MjModel: ...

    @property
    def parameter_names(self) -> tuple[str, ...]: ...

    @property
    def bounds(self) -> np.ndarray: ...

    @property
    def objective_names(self) -> tuple[str, ...]: ...

    @property
    def reward_names(self) -> tuple[str, ...]: ...

    @property
    def episode_seconds(self) -> float: ...

    @property
    def control_steps_per_episode(self) -> int: ...

    def __call__(self, params, key: jax.Array) -> RolloutOutput:
        """(B, P) ``params``, W worlds each drawn from ``key``."""

    def run_worlds(self, params, worlds: Worlds) -> RolloutOutput:
        """(B, P) ``params`` in ``worlds`` of leading shape (B, W) or (W,) (the same for all)."""

    def sample_worlds(self, key: jax.Array, batch: int) -> Worlds:
        """The (batch, W) worlds a call with ``key`` uses."""

    def worlds_per_config(self, key: jax.Array, per_config: int, configs: np.ndarray | None = None) -> Worlds:
        """``per_config`` worlds from each start configuration (default: the training ones)."""

    def trace(self, params, world: Worlds) -> tuple[EpisodeResult, TickRecord]:
        """One parameter vector (P,) in one world: its result and per-tick record."""

    def close(self) -> None:
        """Releases what the engine holds (worker processes); the rollout is unusable after."""


class RolloutBase:
    """What both engines derive the same way from ``task``, ``scenario`` and ``setup`` (the
    attributes of ``Rollout``), and ``with rollout:`` closing it; ``PARAMS_DTYPE`` is the
    engine's float type for parameters."""

    PARAMS_DTYPE: type[np.floating] = np.float64

    if TYPE_CHECKING:  # pragma: no cover
        # What the engines provide (attributes, fields or properties), as ``Rollout`` names them.
        @property
        def scenario(self) -> Scenario: ...

        @property
        def task(self) -> PlannedTask: ...

        @property
        def setup(self) -> EpisodeSetup: ...

        def close(self) -> None: ...

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return self.task.parameter_names

    @property
    def bounds(self) -> np.ndarray:
        """(2, P) lower and upper bounds of the learnable parameters."""
        return self.task.bounds

    @property
    def objective_names(self) -> tuple[str, ...]:
        return self.scenario.objective_names

    @property
    def reward_names(self) -> tuple[str, ...]:
        return tuple(reward.name for reward in self.scenario.rewards)

    @property
    def episode_seconds(self) -> float:
        return self.setup.ticks / self.scenario.bt_hz

    @property
    def control_steps_per_episode(self) -> int:
        return self.setup.ticks * self.setup.steps_per_tick

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def check_params(self, params) -> np.ndarray:
        """``params`` as a (B, P) array of finite values (one (P,) vector is a batch of one)."""
        params = np.atleast_2d(np.asarray(params, self.PARAMS_DTYPE))
        n = len(self.parameter_names)
        if params.ndim != 2 or params.shape[1] != n:
            raise ValueError(f"params must have shape (B, {n}) in the order {list(self.parameter_names)}, got {params.shape}")
        if not np.all(np.isfinite(params)):
            raise ValueError(f"params must be finite, got {params}")
        return params
