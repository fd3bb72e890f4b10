"""The native engine: the same episodes as the compiled one on native MuJoCo, numpy and the
reference BT interpreter, without MJX (the CPU's engine).

``NativeRollout`` (``rollout``) runs a call's episodes in one process on one
``mujoco.batch.Batch`` (``batched``) with the impedance law compiled with numba (``kernels``)
run by MuJoCo as its control callback (``callback``);
``episode`` is one episode as state advanced tick by tick, and ``leaves``, ``controller`` and
``motion`` are the leaf programs, impedance law and motion generator in numpy. Parallelism
wraps it, satisfying the same ``Rollout``: ``ProcessPoolRollout`` (``pool``, with ``worker``:
worker processes on this machine) and ``RayRollout`` (``ray_pool``: the actors of a Ray
cluster). The references the tests and benchmarks check it against (the plain loop over a
call, the numpy lockstep law) are ``mjxskill.engine.native_reference``'s.
"""

from mjxskill.engine.native.pool import ProcessPoolRollout
from mjxskill.engine.native.ray_pool import RayRollout
from mjxskill.engine.native.rollout import NativeRollout

__all__ = ["NativeRollout", "ProcessPoolRollout", "RayRollout"]
