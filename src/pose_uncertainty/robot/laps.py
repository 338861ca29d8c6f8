"""UMBmark squares found in a recording and evaluated with :mod:`..analysis.umbmark`.

The wheel angles with the nominal geometry give the odometry's own motion. Each
wheel sample is a line (``|Δθ| b/2 < 0.05 |Δs|``), a turn in place
(``|Δs| < 0.1 |Δθ| b/2``) or neither; consecutive samples of one kind (pauses skipped)
form pieces. A lap of the square (Borenstein & Feng 1996) is four (line, turn) pairs:
lines of one length within 5 %, turns of one sign each within 0.2 rad of π/2 — "cw"
for right turns, "ccw" for left. Its return-position error is UMBmark's
``ε = true end position − odometry end position`` in the frame of the lap's start
(x along the first leg): the ground truth's displacement in its start frame minus the
odometry's in its own. With at least two laps each way, :func:`..analysis.umbmark.umbmark`
gives E_d and E_b with their delta-method intervals.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..analysis.umbmark import umbmark
from ..core import se2
from ..core.kinematics import integrate
from .align import AlignedRecording, interpolate_poses

__all__ = ["find_laps", "umbmark_from_recording"]


def _pieces(ds: NDArray, dth: NDArray, track: float) -> list[tuple[str, int, int, float, float]]:
    """(kind, first step, end step, Σ Δs, Σ Δθ) of runs of line/turn steps."""
    kind = np.where(np.abs(dth) * track / 2 < 0.05 * np.abs(ds), "line",
                    np.where(np.abs(ds) < 0.1 * np.abs(dth) * track / 2, "turn", "other"))  # fmt: skip
    moving = (np.abs(ds) + np.abs(dth) * track / 2) > 1e-6
    out: list[tuple[str, int, int, float, float]] = []
    for i in np.flatnonzero(moving):
        k = str(kind[i])
        if out and out[-1][0] == k:
            _, a, _, s, t = out[-1]
            out[-1] = (k, a, int(i) + 1, s + float(ds[i]), t + float(dth[i]))
        else:
            out.append((k, int(i), int(i) + 1, float(ds[i]), float(dth[i])))
    return out


def find_laps(rec: AlignedRecording, nominal: tuple[float, float, float]) -> list[dict[str, Any]]:
    """UMBmark laps: ``{direction, start, end, side}`` (wheel indices, side [m]) (module docstring)."""
    rl, rr, b = nominal
    ds = 0.5 * (rr * np.diff(rec.phi_r) + rl * np.diff(rec.phi_l))
    dth = (rr * np.diff(rec.phi_r) - rl * np.diff(rec.phi_l)) / b
    pieces = [p for p in _pieces(ds, dth, b) if p[0] != "other" or abs(p[3]) > 0.01]
    laps, i = [], 0
    while i + 8 <= len(pieces):
        w = pieces[i : i + 8]
        lines, turns = w[0::2], w[1::2]
        ok = all(p[0] == "line" for p in lines) and all(p[0] == "turn" for p in turns)
        if ok:
            lengths = np.array([p[3] for p in lines])
            angles = np.array([p[4] for p in turns])
            sign = np.sign(angles[0])
            ok = bool(lengths.min() > 0 and np.ptp(lengths) < 0.05 * lengths.mean()
                      and np.all(np.sign(angles) == sign) and np.all(np.abs(np.abs(angles) - math.pi / 2) < 0.2))  # fmt: skip
        if ok:
            laps.append({"direction": "ccw" if sign > 0 else "cw", "start": w[0][1], "end": w[-1][2],
                         "side": float(lengths.mean())})  # fmt: skip
            i += 8
        else:
            i += 1
    return laps


def umbmark_from_recording(rec: AlignedRecording, nominal: tuple[float, float, float]) -> dict[str, Any] | None:
    """UMBmark on the laps of the recording (module docstring); None with fewer than 2 laps each way."""
    if rec.truth_t is None or rec.truth_poses is None:
        return None
    laps = find_laps(rec, nominal)
    rl, rr, b = nominal
    truth, ok, _, _ = interpolate_poses(rec.truth_t, rec.truth_poses, rec.t)
    odo = integrate(0.5 * (rr * np.diff(rec.phi_r) + rl * np.diff(rec.phi_l)),
                    (rr * np.diff(rec.phi_r) - rl * np.diff(rec.phi_l)) / b, method="exact")  # fmt: skip
    returns: dict[str, list[NDArray]] = {"cw": [], "ccw": []}
    for lap in laps:
        a, c = lap["start"], lap["end"]
        if not (ok[a] and ok[c]):
            continue
        true_rel = se2.compose(se2.inverse(truth[a]), truth[c])[:2]
        odo_rel = se2.compose(se2.inverse(odo[a]), odo[c])[:2]
        returns[lap["direction"]].append(true_rel - odo_rel)
    counts = {d: len(v) for d, v in returns.items()}
    if min(counts.values()) < 2:
        return {"laps": counts, "result": None, "note": "fewer than 2 UMBmark laps each way"}
    side = float(np.mean([lap["side"] for lap in laps]))
    res = umbmark({d: np.array(v) for d, v in returns.items()}, side, b, None, n_boot=0)
    e = res.estimates
    return {
        "laps": counts, "side": side,
        "E_d": {"value": e["E_d"].value, "ci95": list(e["E_d"].delta), "unit": "1"},
        "E_b": {"value": e["E_b"].value, "ci95": list(e["E_b"].delta), "unit": "1"},
        "E_max_before": e["E_max_before"].value,
        "method": "UMBmark (Borenstein & Feng 1996) on the recorded squares, delta-method intervals",
    }  # fmt: skip
