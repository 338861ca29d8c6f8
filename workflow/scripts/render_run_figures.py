"""Adapter: draw every figure of one run log into its folder (pose_uncertainty.present.pipeline_figures)."""

from contextlib import redirect_stderr
from pathlib import Path

from pose_uncertainty.present.pipeline_figures import render_run_figures

sm = snakemake  # noqa: F821 - injected by Snakemake
kinds = list(sm.params.kinds)
folder = Path(sm.output[0])
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    render_run_figures(sm.input.log, kinds, [folder / f"{kind}.png" for kind in kinds])
