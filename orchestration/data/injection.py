"""Is an injected input inside a logged effort? The steps of the effort at the input's edges.

A lab that adds a known input to the drive command after the controller's saturation
(excitation pulses) logs the effort either where the drive applies it (the controller's
output plus the input: the ``applied`` tap of a record, mast.data.record) or before the
input is added (``before_injection``). At an edge of a pulse train, sample k where the input
jumps, the two differ in one way that the closed loop cannot blur: the loop reacts to the
pulse only from the next sample on (the pulse acts after sample k), so the effort logged
before the injection changes at sample k as at any other sample, while the applied effort
steps by the gain times the input's jump at exactly that sample.

The test: the one-sample changes dy(k) of the effort at the edges, regressed on the input's
jumps du(k) (least squares through 0: the gain g, in effort units per input unit), against
the spread of dy at the other samples (its standard deviation, the samples just after an
edge left out, where the loop answers the pulse; not a robust spread: a drive command's
changes have heavy tails, at the reference's switches, and an edge may fall on one):

    t = g / se(g),  se(g) = spread / sqrt(sum du(k)^2)

The effort steps at the edges (it holds the injected input) when |t| >= STEPS_T and the steps
g du(k) carry at least STEPS_SHARE of the changes at the edges (sum (g du)^2 / sum dy^2: a
few large changes of the effort's own cannot pass for steps); it does not when |t| <=
NO_STEPS_T; between: undecided (the input's step is of the order of the effort's own
sample-to-sample change), no verdict. Edges are the samples where the input jumps by at least
half its range: a pulse train has them, a smooth input (a chirp) has none and is not tested.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

#: |t| at or above (and STEPS_SHARE of the changes at the edges explained): the effort steps with the
#: injected input; at or below NO_STEPS_T: it does not
STEPS_T, NO_STEPS_T, STEPS_SHARE = 10.0, 3.0, 0.5
#: samples after an edge left out of the spread (the loop's answer to the pulse)
AFTER_EDGE = 3


@dataclass(frozen=True)
class EdgeSteps:
    """The effort's steps at the injected input's edges (module docstring)."""

    edges: int  # number of edges of the input
    amplitude: float  # median |jump| of the input at its edges [input unit]
    gain: float  # least-squares step of the effort per unit jump of the input [effort unit / input unit]
    t: float  # gain / its standard error
    share: float  # the share of the effort's changes at the edges the steps explain
    spread: float  # std of the effort's one-sample change away from the edges [effort unit]

    @property
    def step(self) -> float:
        """The effort's step at an edge of the median jump [effort unit]."""
        return self.gain * self.amplitude

    @property
    def steps(self) -> bool:
        return abs(self.t) >= STEPS_T and self.share >= STEPS_SHARE

    @property
    def no_steps(self) -> bool:
        return abs(self.t) <= NO_STEPS_T


def edge_steps(effort: np.ndarray, injected: np.ndarray) -> Optional[EdgeSteps]:
    """The steps of ``effort`` at the edges of ``injected`` (same samples); None when the input has no edge."""
    effort, injected = np.asarray(effort, dtype=float), np.asarray(injected, dtype=float)
    du, dy = np.diff(injected), np.diff(effort)
    span = float(injected.max() - injected.min())
    edge = np.abs(du) >= 0.5 * span if span > 0 else np.zeros(len(du), dtype=bool)
    if not edge.any():
        return None
    near = edge.copy()
    for lag in range(1, AFTER_EDGE + 1):
        near[lag:] |= edge[:-lag]
    away = dy[~near]
    if len(away) < 2:
        return None
    spread = max(float(np.std(away)), np.finfo(float).tiny)
    du_e, dy_e = du[edge], dy[edge]
    energy = float(du_e @ du_e)
    gain = float(dy_e @ du_e) / energy
    changes = float(dy_e @ dy_e)
    share = gain**2 * energy / changes if changes > 0 else 0.0
    return EdgeSteps(
        int(edge.sum()), float(np.median(np.abs(du_e))), gain, gain / (spread / np.sqrt(energy)), share, spread
    )
