"""3PRS mechanism of the MAST: kinematics (``kinematics``), inverse dynamics (``dynamics``)
and the co-simulation block (``model``); the FMI wrapper is ``fmu``. See docs/geometry.md
and docs/mechanism.md."""
