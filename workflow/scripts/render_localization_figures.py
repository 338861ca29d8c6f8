"""Adapter: draw the figures of every localization log of one set into <folder>/<run>/<kind>.png
(pose_uncertainty.present.localization), written into a temporary folder renamed at the end."""

from contextlib import redirect_stderr
from pathlib import Path

from pose_uncertainty.core.atomic import atomic_directory
from pose_uncertainty.present.localization import render_localization_run_figures

sm = snakemake  # noqa: F821 - injected by Snakemake
kinds = list(sm.params.kinds)
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log), atomic_directory(sm.output[0]) as part:
    logs = list(sm.params.logs)
    for i, log_path in enumerate(logs):
        run = Path(log_path).stem
        render_localization_run_figures(log_path, kinds, [part / run / f"{kind}.png" for kind in kinds])
        print(f"render_localization_figures: {i + 1}/{len(logs)} runs drawn ({run})", file=log, flush=True)
