"""Mechanisms of the MAST: the systematic inverse-dynamics engine (``engine``), the mechanism
descriptions built from parameter sets (``designs``), the co-simulation block (``model``) and its
FMI wrappers, one per design (``fmu``); the paper's 3PRS in closed form (``kinematics``,
``dynamics``) is the reference the engine is checked against. See docs/mechanism.md,
docs/geometry.md and docs/designs/."""
