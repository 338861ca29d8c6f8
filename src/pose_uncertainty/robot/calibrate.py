"""``robot calibrate``: a bag in, calibrated constants and navigation-stack parameters out.

Writes into OUTDIR (each file atomically, :mod:`..core.atomic`):

* ``calibration.json`` — ``E_d, E_b, wheel_radius_left, wheel_radius_right, track, k_r, k_l``
  each ``{value, ci95: [lo, hi], unit}`` (also ``std_error``), the nominal geometry and
  where it came from, the ground truth's noise, the held-out checks, UMBmark on the
  recorded squares, the stream counts and the warnings;
* ``ros2_control.yaml``, ``nav2_amcl.yaml``, ``robot_localization.yaml`` (:mod:`.exports`);
* ``horizon.json`` (:mod:`.horizon`);
* ``report.html`` — a self-contained page (inline PNG images) with the figures;
* with ``figure_files``, the figures also as ``drive.png``, ``growth.png`` and
  ``horizon.png`` (:data:`FIGURE_FILES`, at twice the page's resolution), for a report that
  inlines them itself (the pipeline's section "Your robot").

A bag without ground truth is refused with one line (:class:`NoGroundTruth`); the
horizon can still be predicted from known constants (:func:`predict`).
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..core.atomic import atomic_write_bytes, atomic_write_text
from ..core.figure_style import CRISP_RC
from ..core.kinematics import integrate
from ..core.provenance import provenance
from .align import AlignedRecording, align
from .bag import read_bag
from .config import RobotConfig
from .exports import nav2_amcl_yaml, robot_localization_yaml, ros2_control_yaml
from .figures import DPI, growth_figure, horizon_figure, path_figure, plt
from .fit import calibrate_aligned
from .geometry_fit import nominal_from_odometry
from .horizon import horizon
from .laps import umbmark_from_recording
from .nav2 import fit_nav2_alphas

__all__ = ["FIGURE_FILES", "OUTPUT_FILES", "NoGroundTruth", "calibrate_bag", "nominal_geometry", "predict", "stream_warnings"]

OUTPUT_FILES: tuple[str, ...] = (
    "calibration.json", "ros2_control.yaml", "nav2_amcl.yaml", "robot_localization.yaml", "horizon.json", "report.html",
)  # fmt: skip
#: The figure files written with ``figure_files`` (module docstring), by their title on the page.
FIGURE_FILES: dict[str, str] = {"Drive": "drive.png", "Residual growth": "growth.png", "Uncertainty horizon": "horizon.png"}
Say = Callable[[str], None]


class NoGroundTruth(ValueError):
    """The bag has no ground truth: calibration is refused."""


def stream_warnings(rec: AlignedRecording) -> list[str]:
    """One line per stream with problems: what was found and what was done."""
    out = []
    for name, c in rec.counts.items():
        p = c.problems()
        if p:
            what = ", ".join(f"{v} {k.replace('_', ' ')}" for k, v in p.items())
            out.append(f"{name}: {what} (of {c.messages} messages; sorted, first of duplicates kept, wraps undone)")
    return out


def nominal_geometry(rec: AlignedRecording, robot: RobotConfig, src: str) -> tuple[tuple[float, float, float], str]:
    """The nominal (r_l, r_r, b) and where it came from (robot file, else the robot's odometry)."""
    if robot.has_geometry:
        assert robot.radius_left is not None
        assert robot.radius_right is not None
        assert robot.track is not None
        return (robot.radius_left, robot.radius_right, robot.track), "robot file"
    got = nominal_from_odometry(rec)
    if got is None:
        raise ValueError(
            f"{src}: no nominal geometry: give wheel_radius and track in a robot file (--robot), "
            "or record the robot's own odometry topic"
        )
    return got, "the robot's odometry topic"


def _say(progress: Say | None, text: str) -> None:
    if progress is not None:
        progress(text)


def _png_tag(png: bytes, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{base64.b64encode(png).decode()}">'


def _page(cal: dict[str, Any], figures: dict[str, bytes]) -> str:
    rows = "".join(
        f"<tr><td>{k}</td><td>{v['value']:.6g}</td><td>[{v['ci95'][0]:.6g}, {v['ci95'][1]:.6g}]</td><td>{v['unit']}</td></tr>"
        for k, v in cal["quantities"].items()
    )
    ho = cal["held_out"]
    imgs = "".join(f"<h2>{html.escape(name)}</h2>{_png_tag(png, name)}" for name, png in figures.items())
    warn = "".join(f"<li>{html.escape(w)}</li>" for w in cal["warnings"]) or "<li>none</li>"
    return (
        "<!DOCTYPE html><html><head><meta charset='utf-8'><title>Robot calibration</title>"
        "<style>body{font-family:sans-serif;max-width:60em;margin:auto}td,th{padding:2px 8px}</style></head><body>"
        f"<h1>Robot calibration: {html.escape(cal['bag'])}</h1>"
        f"<table><tr><th>quantity</th><th>value</th><th>95 % interval</th><th>unit</th></tr>{rows}</table>"
        f"<p>Held-out segments: {ho['n_segments']}; mean NEES {ho['nees_mean']:.3g} (3 expected, band "
        f"[{ho['nees_band95'][0]:.3g}, {ho['nees_band95'][1]:.3g}]); 95 % ellipse coverage "
        f"{ho['ellipse_coverage']:.3g} (Wilson interval [{ho['ellipse_coverage_ci95'][0]:.3g}, "
        f"{ho['ellipse_coverage_ci95'][1]:.3g}]).</p>"
        f"<h2>Stream problems</h2><ul>{warn}</ul>{imgs}</body></html>\n"
    )


def _paths(rec: AlignedRecording, q: dict[str, Any], nominal: tuple[float, float, float]) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    if rec.truth_poses is not None:
        out["ground truth"] = rec.truth_poses - rec.truth_poses[0] * np.array([1.0, 1.0, 0.0])
    for name, (rl, rr, b) in (("nominal odometry", nominal), ("calibrated odometry", (
            q["wheel_radius_left"]["value"], q["wheel_radius_right"]["value"], q["track"]["value"]))):  # fmt: skip
        dl, dr = rl * np.diff(rec.phi_l), rr * np.diff(rec.phi_r)
        start = rec.truth_poses[0] if rec.truth_poses is not None else np.zeros(3)
        out[name] = integrate((dr + dl) / 2, (dr - dl) / b, start * np.array([0.0, 0.0, 1.0]), method="exact")
    return out


def calibrate_bag(
    bag: str | Path,
    robot: RobotConfig | None,
    outdir: str | Path,
    *,
    seed: int = 0,
    progress: Say | None = None,
    figure_files: bool = False,
) -> dict[str, Any]:
    """Calibrate from ``bag`` and write :data:`OUTPUT_FILES` into ``outdir`` (module docstring).

    Randomness (the nav2 fit's and the horizon's Monte Carlo) comes from
    ``numpy.random.default_rng(seed)``. ``figure_files`` also writes :data:`FIGURE_FILES`.
    Returns the content of ``calibration.json``; its ``units`` give the unit of every number
    outside the quantities (which carry their own).
    """
    cfg = robot if robot is not None else RobotConfig()
    src = str(bag)
    _say(progress, f"reading {src}")
    raw = read_bag(bag, cfg, (lambda d, n: _say(progress, f"  {d}/{n} messages ({100 * d // max(n, 1)} %)")))
    rec = align(raw, cfg)
    warnings = stream_warnings(rec)
    for w in warnings:
        _say(progress, f"warning: {w}")
    if rec.truth_t is None or rec.truth_t.size < 2:
        raise NoGroundTruth(
            f"{src}: no ground truth in the bag (topics: {', '.join(f'{k}={v}' for k, v in raw.topics.items())}): "
            "calibration refused; predict with known constants instead (robot predict)"
        )
    nominal, nominal_source = nominal_geometry(rec, cfg, src)
    _say(progress, f"fitting geometry and wheel noise (nominal from {nominal_source})")
    fit = calibrate_aligned(rec, nominal, cfg.truth_std)
    q = fit.quantities()
    rng = np.random.default_rng(seed)
    _say(progress, "fitting nav2 AMCL alphas")
    geo = (q["wheel_radius_left"]["value"], q["wheel_radius_right"]["value"], q["track"]["value"])
    ks = (q["k_r"]["value"], q["k_l"]["value"])
    nav2 = fit_nav2_alphas(rec.phi_l, rec.phi_r, geo, ks, rng, cfg.update_min_d, cfg.update_min_a).as_dict()
    _say(progress, "predicting the uncertainty horizon")
    hz = horizon(ks[0], ks[1], geo[2], cfg.nominal_speed, cfg.horizon_thresholds, cfg.turn_radius, rng)
    cal = {
        "bag": src, "topics": raw.topics, "quantities": q, **q,
        "nominal": {"wheel_radius_left": nominal[0], "wheel_radius_right": nominal[1], "track": nominal[2],
                    "source": nominal_source},
        "ground_truth_noise": {k: v for k, v in fit.noise.as_dict().items() if k.startswith("truth")},
        "held_out": fit.held_out, "n_segments": len(fit.segments),
        "umbmark": umbmark_from_recording(rec, nominal),
        "nav2_amcl": nav2,
        "streams": {k: vars(v) for k, v in rec.counts.items()},
        "warnings": warnings, "seed": seed,
        "units": {"nominal": "m", "ground_truth_noise": {"truth_position_std": "m", "truth_heading_std": "rad"},
                  "held_out": {"nees_mean": "1", "nees_band95": "1", "ellipse_coverage": "1", "n_segments": "1"},
                  "nav2_amcl": {"alpha1": "1", "alpha2": "rad^2/m^2", "alpha3": "1", "alpha4": "m^2/rad^2",
                                "update_min_d": "m", "update_min_a": "rad", "coverage": "1"}},
        "provenance": provenance(),
        "methods": {
            "geometry": "generalised least squares on segment increments; 95 % = value +- 1.96 se (Fisher)",
            "k": "maximum likelihood of segment residuals under Method A; 95 % profile-likelihood intervals",
        },
    }  # fmt: skip
    out = Path(outdir)
    draw = {
        "Drive": lambda dpi: path_figure(_paths(rec, q, nominal), dpi),
        "Residual growth": lambda dpi: growth_figure(fit.segments.travel, fit.residuals, fit.covariances, dpi),
        "Uncertainty horizon": lambda dpi: horizon_figure(hz, dpi),
    }
    figures = {name: fn(DPI) for name, fn in draw.items()}
    if figure_files:  # for the pipeline's report, at 2× and without anti-aliasing, as its own figures (CRISP_RC)
        with plt.rc_context(CRISP_RC):  # type: ignore[arg-type]
            for name, fn in draw.items():
                atomic_write_bytes(out / FIGURE_FILES[name], fn(2 * DPI))
    atomic_write_text(out / "calibration.json", json.dumps(cal, indent=2, default=float) + "\n")
    atomic_write_text(out / "ros2_control.yaml", ros2_control_yaml(q, nominal, cfg.nominal_speed, cfg.update_rate,
                                                                   cfg.covariance_distance))  # fmt: skip
    atomic_write_text(out / "nav2_amcl.yaml", nav2_amcl_yaml(nav2))
    atomic_write_text(out / "robot_localization.yaml", robot_localization_yaml(
        q, cfg.nominal_speed, cfg.update_rate, raw.topics.get("odometry", "/odom")))  # fmt: skip
    atomic_write_text(out / "horizon.json", json.dumps(hz, indent=2) + "\n")
    atomic_write_text(out / "report.html", _page(cal, figures))
    _say(progress, f"wrote {', '.join(OUTPUT_FILES)} in {out}")
    return cal


def predict(
    k_r: float, k_l: float, track: float, robot: RobotConfig, outdir: str | Path, *, seed: int = 0
) -> dict[str, Any]:
    """The horizon from known constants (no ground truth needed): ``horizon.json`` and its figure page."""
    hz = horizon(k_r, k_l, track, robot.nominal_speed, robot.horizon_thresholds, robot.turn_radius,
                 np.random.default_rng(seed))  # fmt: skip
    out = Path(outdir)
    atomic_write_text(out / "horizon.json", json.dumps(hz, indent=2) + "\n")
    page = ("<!DOCTYPE html><html><head><meta charset='utf-8'><title>Uncertainty horizon</title></head><body>"
            f"<h1>Uncertainty horizon</h1>{_png_tag(horizon_figure(hz), 'horizon')}</body></html>\n")  # fmt: skip
    atomic_write_text(out / "report.html", page)
    return hz
