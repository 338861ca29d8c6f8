"""Adapter: render reports/comparison.html (pose_uncertainty.report.build_report)."""

import sys

sys.stderr = open(snakemake.log[0], "w", encoding="utf-8")  # noqa: F821

import yaml  # noqa: E402

from pose_uncertainty.report import build_report  # noqa: E402

manifest = snakemake.params.manifest  # noqa: F821
build_report(
    manifest,
    dict(zip(snakemake.params.sets, snakemake.input.tables, strict=True)),  # noqa: F821
    snakemake.input.claims,  # noqa: F821
    list(snakemake.input.benchmarks),  # noqa: F821
    snakemake.output[0],  # noqa: F821
    title=snakemake.params.title,  # noqa: F821
    config_text=yaml.safe_dump(manifest["config"], sort_keys=False, width=100),
)
