"""Upper bounds of the evaluation's numbers (``evaluate``, ``experiment``, ``explore`` and
``experiment.yaml``), far beyond any use, for the reason the run settings have theirs
(``mjxskill.scenario.schema``): a typo must be refused before anything is written, not exhaust
the machine (``evaluate --random 10**9`` was a MemoryError traceback). Imports nothing: the
commands' parsers read it before mujoco may be imported."""

MAX_PER_CONFIG = 1000  # evaluation or validation worlds per start configuration; the paper's evaluation has 5
MAX_RANDOM_SETS = 10_000  # random parameter sets of an evaluation; the paper has 10
MAX_VALIDATION_CANDIDATES = 100  # solutions the pick's validation rolls out again; default 3

__all__ = ["MAX_PER_CONFIG", "MAX_RANDOM_SETS", "MAX_VALIDATION_CANDIDATES"]
