"""What the paper reports, in one place (Roldan-Paraponiaris, Campa, Altuzarra; ../shared/paper.md).

Every number carries where it comes from; the reproduction and the gain
identification both read them from here.
"""
from __future__ import annotations

import math

#: closed-loop position response, section 4.2: frequency [Hz] -> (magnitude [-], phase [deg])
POSITION_RESPONSE = {0.4: (0.994, -6.3), 5.0: (0.654, -62.5), 10.0: (0.432, -103.7)}
#: the paper's own simulation-vs-experiment deviation (section 4.2): the tolerance of a match
TOLERANCE_MAGNITUDE = 0.11   # relative
TOLERANCE_PHASE_DEG = 13.0   # degrees
#: -3 dB bandwidths, section 4.1 / Fig. 10 [Hz]
BANDWIDTH_WITH_MAST = 3.5
BANDWIDTH_ACTUATORS_ALONE = 4.0
#: "up to 2 Hz both systems behave similarly" (Fig. 10) [Hz]
ALIKE_UP_TO_HZ = 2.0
#: Fig. 7 / Table 1 [Hz]
TF2_RESONANCE_FIG7 = 900.0
FN_TABLE1 = 986.5
#: section 4.2, torques: manufacturer vs measured/identified
TORQUE_DIFFERENCE_04HZ = 0.10      # N m, |identified - manufacturer| at 0.4 Hz ("approximately 0.10 Nm")
TORQUE_ERROR_MANUFACTURER_04HZ = 0.70  # relative ("differs ... by approximately 70 %")
TORQUE_EXCESS_MANUFACTURER_10HZ = 0.10  # N m, manufacturer above measured at 10 Hz
SQUARE_WAVE_H3_H1 = 1.0 / 3.0      # "almost a square signal" at 0.4 Hz: 3rd/1st harmonic of a square wave
#: the identified physical variant (section 4.2), as parameter overrides of each actuator
IDENTIFIED = {"J1_scale": 1.0 / 1.56, "tau_c": 7.18e-2}
#: test amplitudes: not in the paper (assumed: the largest that keeps the drives out of current
#: saturation up to 10 Hz with the default system: 5 mm in z, 0.8 deg in psi/theta, about 4.9 mm at the joints)
AMPLITUDE = {"z": 0.005, "psi": math.radians(0.8), "theta": math.radians(0.8)}
