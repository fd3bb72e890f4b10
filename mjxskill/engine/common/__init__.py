"""What both physics engines share: the static facts of an episode and its result types
(``types``), scenario objects <-> MJCF bodies (``bindings``), domain randomization (``worlds``),
quaternions (``rotations``) and the motion generator's limits (``motion``). Nothing here imports
MJX."""
