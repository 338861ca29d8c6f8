# Per-run measures collected into one CSV per experiment set.


rule collect_metrics:
    input:
        runs=lambda w: runs_made(w.set, timings=True),
    output:
        report(
            "reports/tables/{set}.csv",
            caption="../report/table.rst",
            category="{set}",
            subcategory="tables",
            labels={"table": "per-run measures"},
        ),
    params:
        logs=lambda w: run_logs(w.set),
        timings=lambda w: run_timings(w.set),
        source=script_source("collect_metrics"),
    log:
        "logs/collect_metrics/{set}.log",
    benchmark:
        "data/benchmarks/collect_metrics/{set}.tsv"
    script:
        "../scripts/collect_metrics.py"
