"""UMBmark squares found in a recording and evaluated with :mod:`..analysis.umbmark`.

The wheel angles with the nominal geometry give the odometry's own motion. Each
wheel sample is a line (``|Δθ| b/2 < 0.05 |Δs|``), a turn in place
(``|Δs| < 0.1 |Δθ| b/2``) or neither; consecutive samples of one kind (pauses skipped)
form pieces. A recording is not a clean command: encoder ticks quantise each sample's
travel, so a few slow samples where the robot starts or stops fall in the wrong class,
and a controller corrects the heading on a leg. So pieces of less than
:data:`MIN_PIECE` of motion (travel plus ``|Δθ| b/2``) are dropped as such blips and the
pieces of one kind left next to each other are merged. A lap of the square (Borenstein &
Feng 1996) is then four (line, turn) pairs: lines of one length within 5 %, turns of one
sign each within 0.2 rad of π/2 — "cw" for right turns, "ccw" for left. It starts where
its first leg starts and ends where the robot next moves (the next lap's first leg), so
that blips dropped at the end of its last turn, still at the corner, stay in the lap.

Its return-position error is UMBmark's ``ε = true end position − odometry end position``
in the frame of the lap's start (x along the first leg): the ground truth's displacement
in its start frame minus the odometry's in its own. A lap starts and ends at rest (UMBmark
stops at each corner), so where the ground truth does not cover the lap's first or last
wheel stamp (the recording's first lap: the ground truth's stream starts a few ms after
the wheels'), its nearest sample is taken when it lies within one ground-truth interval and
the wheels moved less than :data:`REST` between the two stamps. With at least two laps each
way, :func:`..analysis.umbmark.umbmark` gives E_d and E_b with their delta-method intervals.
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

__all__ = ["MIN_PIECE", "REST", "find_laps", "lap_returns", "umbmark_from_recording"]

#: Pieces of less motion than this [m] (travel plus ``|Δθ| b/2``) are blips, not legs or turns (module docstring).
MIN_PIECE: float = 0.01
#: Wheel travel [m] below which the robot counts as at rest between a lap's end and a ground-truth sample.
REST: float = 1e-4


def _pieces(ds: NDArray, dth: NDArray, track: float) -> list[tuple[str, int, int, float, float]]:
    """(kind, first step, end step, Σ Δs, Σ Δθ) of runs of line/turn steps, blips dropped and merged."""
    kind = np.where(np.abs(dth) * track / 2 < 0.05 * np.abs(ds), "line",
                    np.where(np.abs(ds) < 0.1 * np.abs(dth) * track / 2, "turn", "other"))  # fmt: skip
    moving = (np.abs(ds) + np.abs(dth) * track / 2) > 1e-6
    runs: list[tuple[str, int, int, float, float]] = []
    for i in np.flatnonzero(moving):
        runs = _extend(runs, (str(kind[i]), int(i), int(i) + 1, float(ds[i]), float(dth[i])))
    out: list[tuple[str, int, int, float, float]] = []
    for p in runs:
        if abs(p[3]) + abs(p[4]) * track / 2 >= MIN_PIECE:
            out = _extend(out, p)
    return out


def _extend(pieces: list[tuple[str, int, int, float, float]],
            p: tuple[str, int, int, float, float]) -> list[tuple[str, int, int, float, float]]:  # fmt: skip
    """``pieces`` with ``p`` appended, or merged into the last piece when it is of the same kind."""
    if pieces and pieces[-1][0] == p[0]:
        k, a, _, s, t = pieces[-1]
        return [*pieces[:-1], (k, a, p[2], s + p[3], t + p[4])]
    return [*pieces, p]


def find_laps(rec: AlignedRecording, nominal: tuple[float, float, float]) -> list[dict[str, Any]]:
    """UMBmark laps: ``{direction, start, end, side}`` (wheel indices, side [m]) (module docstring)."""
    rl, rr, b = nominal
    ds = 0.5 * (rr * np.diff(rec.phi_r) + rl * np.diff(rec.phi_l))
    dth = (rr * np.diff(rec.phi_r) - rl * np.diff(rec.phi_l)) / b
    pieces = _pieces(ds, dth, b)
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
            # the lap ends where the robot next moves (or the recording ends): the last turn's slow
            # samples dropped as blips are still at the corner, and the next lap starts right there
            end = pieces[i + 8][1] if i + 8 < len(pieces) else int(ds.size)
            laps.append({"direction": "ccw" if sign > 0 else "cw", "start": w[0][1], "end": end,
                         "side": float(lengths.mean())})  # fmt: skip
            i += 8
        else:
            i += 1
    return laps


def _truth_at_rest(rec: AlignedRecording, nominal: tuple[float, float, float]) -> tuple[NDArray, NDArray]:
    """The ground truth at every wheel stamp, and where it is known; a stamp just outside the
    ground truth's span takes its nearest sample when the robot is at rest in between (module docstring)."""
    assert rec.truth_t is not None
    assert rec.truth_poses is not None
    truth, ok, _, _ = interpolate_poses(rec.truth_t, rec.truth_poses, rec.t)
    gap = float(np.median(np.diff(rec.truth_t)))
    rl, rr, _ = nominal
    for end, j in ((rec.t < rec.truth_t[0], 0), (rec.t > rec.truth_t[-1], -1)):
        near = end & (np.abs(rec.t - rec.truth_t[j]) <= gap)
        if near.any():
            tj = np.full(int(near.sum()), rec.truth_t[j])
            moved = (rl * np.abs(np.interp(tj, rec.t, rec.phi_l) - rec.phi_l[near])
                     + rr * np.abs(np.interp(tj, rec.t, rec.phi_r) - rec.phi_r[near]))  # fmt: skip
            rest = np.flatnonzero(near)[moved < REST]
            truth[rest], ok[rest] = rec.truth_poses[j], True
    return truth, ok


def lap_returns(rec: AlignedRecording, nominal: tuple[float, float, float]) -> tuple[list[dict[str, Any]], dict[str, list[NDArray]]]:
    """The laps (:func:`find_laps`) and the return-position errors of those with ground truth at both ends, by direction."""
    laps = find_laps(rec, nominal)
    rl, rr, b = nominal
    truth, ok = _truth_at_rest(rec, nominal)
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
    return laps, returns


def umbmark_from_recording(rec: AlignedRecording, nominal: tuple[float, float, float]) -> dict[str, Any] | None:
    """UMBmark on the laps of the recording (module docstring); None with fewer than 2 laps each way."""
    if rec.truth_t is None or rec.truth_poses is None:
        return None
    laps, returns = lap_returns(rec, nominal)
    b = nominal[2]
    counts = {d: len(v) for d, v in returns.items()}
    found = {d: sum(lap["direction"] == d for lap in laps) for d in returns}
    if min(counts.values()) < 2:
        return {"laps": counts, "laps_found": found, "result": None, "note": "fewer than 2 UMBmark laps each way"}
    side = float(np.mean([lap["side"] for lap in laps]))
    res = umbmark({d: np.array(v) for d, v in returns.items()}, side, b, None, n_boot=0)
    e = res.estimates
    return {
        "laps": counts, "laps_found": found, "side": side,
        "E_d": {"value": e["E_d"].value, "ci95": list(e["E_d"].delta), "unit": "1"},
        "E_b": {"value": e["E_b"].value, "ci95": list(e["E_b"].delta), "unit": "1"},
        "E_max_before": e["E_max_before"].value,
        "method": "UMBmark (Borenstein & Feng 1996) on the recorded squares, delta-method intervals",
    }  # fmt: skip
