"""Native-MuJoCo baseline: the compiled rollout's episodes in a plain Python loop over
``mujoco.mj_step`` with the numpy impedance controller and the reference BT interpreter."""

from mjxskill.engine.native.rollout import NativeRollout

__all__ = ["NativeRollout"]
