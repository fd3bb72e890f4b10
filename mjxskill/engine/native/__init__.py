"""The native engine: the same episodes as the compiled one on native MuJoCo, numpy and the
reference BT interpreter, without MJX (the CPU's engine).

Modules: ``rollout`` (``NativeRollout``), ``batched`` (many episodes on one
``mujoco.batch.Batch``, the production path) with ``kernels`` (its impedance law compiled with
numba), ``episode`` (one episode as state advanced tick by tick), ``leaves``, ``controller`` and
``motion`` (the leaf programs, impedance law and motion generator in numpy), ``lockstep`` (the
same episodes stepped in lockstep in numpy, the kernels' test reference), ``pool`` and
``worker`` (worker processes), ``ray_pool`` (Ray actors).
"""

from mjxskill.engine.native.rollout import NativeRollout

__all__ = ["NativeRollout"]
