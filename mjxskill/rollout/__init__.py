"""Rollouts: the compiled BT driving the impedance controller in domain-randomized MJX worlds,
rewards grouped into objectives. ``compile_rollout`` is the entry point."""

from mjxskill.rollout.compiled import Rollout, RolloutOutput, compile_rollout, load_model
from mjxskill.rollout.worlds import Worlds

__all__ = ["Rollout", "RolloutOutput", "Worlds", "compile_rollout", "load_model"]
