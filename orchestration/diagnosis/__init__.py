"""``mast diagnose``: find where simulation and measurement disagree, name the missing effect,
add it, show the gap shrink (docs/diagnose.md).

1. Localise: simulate the nominal model on every measured test, driven by the recorded
   joint commands; per test and signal: fit %, NRMSE and where the residual concentrates.
2. Name: regress the torque residual on the signatures of the effect library
   (diagnosis/effects.py), linearised at the current model. Every subset of effects
   is scored by BIC on the training tests; a subset is admissible only if each of its
   members is needed (removing it costs >= 10 in BIC *and* a measurable part of the
   held-out residual) and its parameters are physical.
3. Add and fit: the selected parameters by bounded least squares on the training tests,
   re-simulating the co-simulation at every step (start: the regression estimate;
   Jacobian: the effect signatures of the current simulation). Steps 2-3 repeat,
   re-linearised at the fitted model, until the selection stops changing.
   Backlash, which makes the loop hunt (unpredictably sample by sample), comes last, on a
   phase-free score: band powers of the residual against ensembles of re-simulations
   (diagnosis/phasefree.py).
4. Show: re-simulate every test; diagnosis.json, report.md with figures, the augmented
   parameter set (actuator_diagnosed.ssv) and an SSP that binds it.
5. The verdict: nothing missing (residual at the noise floor), explained (at the floor
   sample by sample, or by the band powers where a named backlash makes the loop hunt), or
   an unexplained residual (shown, never forced onto a name).
"""

from .options import Options
from .resimulation import DiagnosisError
from .workflow import diagnose

__all__ = ["DiagnosisError", "Options", "diagnose"]
