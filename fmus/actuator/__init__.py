"""Actuator FMU: one MAST linear axis (Maxon RE 40 + GP 42 C + igus ZLW-1040 belt guide).

``model.ActuatorBlock`` takes the voltage command ``u`` [V] and the force ``F`` [N] the
axis applies to the mechanism, and returns the carriage position, velocity and
acceleration and the motor angle, speed, current and torque; ``drive.DriveActuatorBlock``
(the FMU's model) puts the drive's PI current loop in front of it: current command in. The transmission is rigid
(n_dof = 1), the paper's two-inertia model (n_dof = 2, Eqs. 1-3 and 20-23) or an N-inertia
chain. See docs/actuator.md.
"""
