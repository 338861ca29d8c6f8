"""Adapter: provenance from every log, seeds and rule times (pose_uncertainty.pipeline.summary)."""

from contextlib import redirect_stderr

from pose_uncertainty.pipeline.summary import summarize_pipeline

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    summarize_pipeline(
        dict(zip(sm.params.sets, sm.input.tables, strict=True))
        | dict(zip(sm.params.loc_sets, sm.input.loc_tables, strict=True)),  # localization/<set>
        list(sm.input.studies),
        list(sm.params.benchmarks),
        sm.output[0],
    )
