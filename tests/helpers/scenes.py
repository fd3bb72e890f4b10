"""Facts of the shipped MJCF scenes the tests check against (the package reads them from the
scenario YAML and the MJCF, never from here)."""

# Peg scenes (assets/peg.xml, round; assets/peg_square.xml): the hole's top above the box frame,
# its depth, and the clearance between the peg and the hole's wall (radius, or on each side) (m).
HOLE_TOP = 0.05
HOLE_DEPTH = 0.04
HOLE_CLEARANCE = 0.0015
