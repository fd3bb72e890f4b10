"""A scripted stand-in for either engine in evaluation tests: closed-form outcomes per (parameter
set, world), so that success rates, forces and times can be computed again by brute force."""

from __future__ import annotations

from typing import NamedTuple
from types import SimpleNamespace

import numpy as np


class ScriptWorlds(NamedTuple):  # a pytree, as the engines' Worlds are
    config_index: np.ndarray
    world: np.ndarray  # a world's number within its configuration


class ScriptedRollout:
    """World (c, r) of a candidate p succeeds when (7 r + 3 c + round(100 p_0)) % 10 < 10 s(p),
    s(p) = the first parameter's position in its bounds; the commanded force of every world is
    10 |p_1| N; a success ends the tree at tick 4 + (r + c) % 3, a failure never does.
    ``stop_after``: calls before a KeyboardInterrupt (a Ctrl-C during an evaluation)."""

    def __init__(self, scenario, bounds, stop_after: int | None = None):
        self.scenario, self.lo, self.hi = scenario, np.asarray(bounds[0]), np.asarray(bounds[1])
        self.calls, self.stop_after = [], stop_after

    def worlds_per_config(self, key, per_config, configs):
        n = len(configs)
        return ScriptWorlds(np.repeat(np.arange(n), per_config), np.tile(np.arange(per_config), n))

    def outcome(self, p, c, r):
        s = (p[0] - self.lo[0]) / (self.hi[0] - self.lo[0])
        success = (7 * r + 3 * c + int(round(100 * p[0]))) % 10 < 10 * s
        return success, 10 * abs(p[1]), (4 + (r + c) % 3) if success else -1

    def run_worlds(self, params, worlds):
        if self.stop_after is not None and len(self.calls) == self.stop_after:
            raise KeyboardInterrupt
        self.calls.append(np.array(params))
        # unseen configurations follow the known ones: number them on
        n_known = len(self.scenario.robot.start_configs)
        per_config = int(worlds.world.max()) + 1
        cfg = np.where(np.arange(len(worlds.config_index)) >= n_known * per_config, worlds.config_index + n_known,
                       worlds.config_index)
        out = np.array([[self.outcome(p, c, r) for c, r in zip(cfg, worlds.world)] for p in params], np.float64)
        return SimpleNamespace(success=out[..., 0] > 0, metrics={"peak_commanded_force": out[..., 1], "bt_done_tick": out[..., 2],
                                                                 "position_error": 0.001 * (1 - out[..., 0]),
                                                                 "peak_contact_force": 1.5 * out[..., 1],
                                                                 "mean_contact_force": 0.5 * out[..., 1]})


def expected(rollout: ScriptedRollout, params, n_cfg: int, per_config: int, bt_hz: float):
    """Brute force: (success (N, C), peak_commanded_force (N,), success_seconds (N, C)) of ``params``."""
    n = len(params)
    success, force, seconds = np.zeros((n, n_cfg)), np.zeros(n), np.full((n, n_cfg), np.nan)
    for i, p in enumerate(params):
        forces = []
        for c in range(n_cfg):
            times = []
            for r in range(per_config):
                ok, f, tick = rollout.outcome(p, c, r)
                success[i, c] += ok / per_config
                forces.append(f)
                if ok:
                    times.append((tick + 1) / bt_hz)
            if times:
                seconds[i, c] = np.mean(times)
        force[i] = np.mean(forces)
    return success, force, seconds
