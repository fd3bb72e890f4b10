"""The physics engines: one ``Rollout`` interface, two implementations, and which one a run uses.

``common``: what both engines share (episode setup and results, scene bindings, domain
randomization, the math written once for both); ``mjx``: the compiled rollout (MJX, every
episode of a call in one XLA program); ``native``: the same episodes on native MuJoCo, in one
process or wrapped by worker processes or a Ray cluster. ``build.build_rollout`` builds either;
``build.resolve_engine`` says which ``auto`` means here; ``build.connect_cluster`` connects a Ray
cluster. ``native_reference``: what the native engine is checked against (tests, benchmarks).
"""

from mjxskill.engine.build import CHOICES, ENGINES, build_rollout, connect_cluster, resolve_engine

__all__ = ["CHOICES", "ENGINES", "build_rollout", "connect_cluster", "resolve_engine"]
