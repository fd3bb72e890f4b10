"""What both physics engines share: the static facts of an episode and its result types
(``types``), scenario objects <-> MJCF bodies (``bindings``), domain randomization (``worlds``),
quaternions (``rotations``), the tool's orientation conventions (``tool``), the motion
generator's limits (``motion``) and the PRNG keys the worlds are drawn from (``keys``). Nothing
here imports MJX."""
