"""Trajectory FMU: a pose command for the MAST, so a system runs without a stimulus from the host.

``model.TrajectoryBlock`` outputs ``<c>_cmd`` for the mechanism's coordinates (the 3PRS's ``z_cmd``,
``psi_cmd``, ``theta_cmd``; ``TrajectoryBlock.for_coordinates`` for another topology): a home pose plus a
sine on each axis (amplitudes and one frequency are parameters; set one amplitude to move one
axis). It feeds the controller in ``ssp/MAST_standalone.ssd``, the system that third-party
co-simulation hosts run as it is.
"""
