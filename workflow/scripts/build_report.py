"""Adapter: render reports/comparison.html and its companion pages in reports/runs/ (present.report.build_report)."""

from contextlib import redirect_stderr

import yaml

from pose_uncertainty.present.report import build_report

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    build_report(
        sm.params.manifest,
        dict(zip(sm.params.sets, sm.input.tables, strict=True)),
        sm.input.claims,
        sm.input.pipeline,
        sm.output.report,
        title=sm.params.title,
        config_text=yaml.safe_dump(sm.params.manifest["config"], sort_keys=False, width=100),
        studies_path=sm.input.studies[0] if len(sm.input.studies) else None,
        studies_figures=dict(sm.params.studies_figures),
        speed_dir="benchmarks/results",
        localization=sm.params.manifest.get("localization"),
        localization_tables=dict(zip(sm.params.loc_sets, sm.input.loc_tables, strict=True)),
        robots=list(sm.params.robots),
        runs_out=sm.output.runs,
    )
