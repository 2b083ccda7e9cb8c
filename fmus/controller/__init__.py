"""Joint-space cascade controller of the MAST (paper Fig. 1, 2 and 6).

One drive controller for the n linear axes of the mechanism (the 3PRS's three): the pose command (for
the 3PRS z, psi, theta) goes through the controller's own kinematic model (the mechanism's inverse
kinematics code, bound to the controller's geometry parameter set) to joint
position commands; each axis then runs a sampled cascade of a P position loop
(k_v, every T_pos) and a PI velocity loop (k_p, k_i, every T_vel), with command limits
and anti-windup, whose current command goes to the PI current loop inside the actuator
(fmus/actuator/drive.py).

``model.ControllerBlock`` holds the equations (see docs/controller.md for the
difference equations, the timing and the computation delay); the FMI wrapper,
if any, lives apart from it.
"""
