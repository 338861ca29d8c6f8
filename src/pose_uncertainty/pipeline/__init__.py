"""pipeline layer: what the Snakemake jobs run and what they collect.

The job entry points (:mod:`.jobs`: execute one run and write its log), the per-set tables
(:mod:`.tables`), the pipeline's provenance summary (:mod:`.summary`), and the claims with the
method guide (:mod:`.claims`).
"""
