"""The calibration of one aligned recording: geometry and wheel noise together, then held-out checks.

The systematic (geometry, :mod:`.geometry_fit`) and random (noise, :mod:`.noise_fit`)
parts are fitted in turn, three rounds: the geometry by least squares weighted with
the current noise model, then the noise by maximum likelihood of the residuals of the
current geometry (the Gaussian's mean and covariance parameters are asymptotically
independent, so alternating converges to the joint maximum). The first weights use
``k = 10⁻⁴`` m and a ground-truth noise of 1 mm and 1 mrad.

Goodness of fit: every fifth segment is held out (five is prime to the four cycled
segment lengths, so every length is held out), the whole fit is repeated on the other
four fifths, and the held-out residuals are checked against that fit's
predictive covariances — the noise model's plus the fitted geometry's own uncertainty
``J Cov(θ̂) Jᵀ`` (NEES and the coverage of the 95 % ellipses, :func:`.noise_fit.held_out_check`).
The reported constants come from all segments. The NEES band assumes known
parameters; the fitted ones' own estimation error raises the expected held-out NEES by
roughly ``2p/J`` (p fitted noise parameters, J fitting segments), a few tenths here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .align import AlignedRecording
from .geometry_fit import GeometryFit, fit_geometry, geometry_jacobian
from .noise_fit import NoiseFit, fit_noise, held_out_check, model_covariances, noise_matrices
from .segments import Segments, cut_segments, predict, residuals

__all__ = ["CALIBRATION_KEYS", "CalibrationFit", "calibrate_aligned", "calibrate_segments"]

#: The quantities of ``calibration.json``, in order.
CALIBRATION_KEYS: tuple[str, ...] = ("E_d", "E_b", "wheel_radius_left", "wheel_radius_right", "track", "k_r", "k_l")
_ROUNDS = 3
_START_PSI = np.array([1e-4, 1e-4, 1e-6, 1e-6])


@dataclass(frozen=True, eq=False)
class CalibrationFit:
    """Geometry and noise fitted to the segments, and the held-out check."""

    geometry: GeometryFit
    noise: NoiseFit
    segments: Segments
    residuals: NDArray[np.float64]
    covariances: NDArray[np.float64]
    held_out: dict[str, Any]

    def quantities(self) -> dict[str, dict[str, Any]]:
        """The :data:`CALIBRATION_KEYS`, each ``{value, ci95, unit, std_error}``."""
        out = self.geometry.quantities(self.noise.level)
        n = self.noise.as_dict()
        for k in ("k_r", "k_l"):
            out[k] = {key: n[k][key] for key in ("value", "ci95", "unit", "std_error")}
        return {k: out[k] for k in CALIBRATION_KEYS}


def calibrate_segments(
    seg: Segments,
    nominal: tuple[float, float, float],
    truth_std: tuple[float, float] | None = None,
    level: float = 0.95,
    intervals: bool = True,
) -> tuple[GeometryFit, NoiseFit, NDArray, NDArray]:
    """Alternate the geometry and noise fits (module docstring); also the residuals and covariances.

    The noise's profile-likelihood intervals (``intervals``) are computed in the last round only.
    """
    theta = np.array(nominal, dtype=np.float64)
    psi = _START_PSI.copy()
    if truth_std is not None:
        psi[2:] = np.square(truth_std)
    geo = noise = None
    for i in range(_ROUNDS):
        Sigma = model_covariances(psi, noise_matrices(seg, *theta))
        geo = fit_geometry(seg, (theta[0], theta[1], theta[2]), Sigma, nominal)
        theta = geo.theta
        r = residuals(seg, predict(seg, *theta))
        M = noise_matrices(seg, *theta)
        noise = fit_noise(r, M, truth_std, level, intervals and i == _ROUNDS - 1)
        psi = noise.psi
    assert geo is not None
    assert noise is not None
    return geo, noise, r, model_covariances(psi, M)


def calibrate_aligned(
    rec: AlignedRecording,
    nominal: tuple[float, float, float],
    truth_std: tuple[float, float] | None = None,
    level: float = 0.95,
) -> CalibrationFit:
    """Calibrate a recording with ground truth (module docstring).

    Parameters
    ----------
    rec : AlignedRecording — must hold ground truth
    nominal : (r_l, r_r, b) [m] — the robot odometry's geometry (the fit's start, and E_b's base)
    truth_std : (σ_p [m], σ_θ [rad]) or None — the ground truth's noise, given (None: fitted)
    """
    seg = cut_segments(rec, 0.5 * (nominal[0] + nominal[1]))
    if len(seg) < 16:
        raise ValueError(
            f"the recording gives only {len(seg)} independent segments with ground truth "
            "(need at least 16: drive longer, e.g. UMBmark squares both ways)"
        )
    geo, noise, r, Sigma = calibrate_segments(seg, nominal, truth_std, level)
    held = np.arange(len(seg)) % 5 == 4
    train_geo, train_noise, _, _ = calibrate_segments(seg.take(~held), nominal, truth_std, level, False)
    test = seg.take(held)
    r_test = residuals(test, predict(test, *train_geo.theta))
    # the predictive covariance: the noise model plus the fitted geometry's own uncertainty
    _, Jr = geometry_jacobian(test, train_geo.theta)
    S_test = model_covariances(train_noise.psi, noise_matrices(test, *train_geo.theta))
    S_test = S_test + Jr @ train_geo.cov @ np.swapaxes(Jr, -1, -2)
    check = held_out_check(r_test, S_test, level)
    return CalibrationFit(geo, noise, seg, r, Sigma, check)
