# Figures: per set, of every run (the same functions `pose-uncertainty replay --figures` uses), and
# set-level figures. One job draws all runs of a set (each log read once): a Python process per run
# cost more than its figures.


rule render_run_figures:
    input:
        runs=lambda w: runs_made(w.set),
    output:
        report(
            directory("reports/figures/{set}/runs"),
            patterns=["{run}/{name}.png"],
            caption="../report/run_figures.rst",
            category="{set}",
            subcategory="{run}",
            labels={"run": "{run}", "figure": "{name}"},
        ),
    params:
        source=script_source("render_run_figures"),
        logs=lambda w: run_logs(w.set),
        kinds=lambda w: {r.id: list(run_figures(w.set, r)) for r in RUNS[w.set]},
    log:
        "logs/render_run_figures/{set}.log",
    benchmark:
        "data/benchmarks/render_run_figures/{set}.tsv"
    script:
        "../scripts/render_run_figures.py"


rule render_growth_figure:
    input:
        runs=lambda w: runs_made(w.set),
    output:
        report(
            "reports/figures/{set}/growth.png",
            caption="../report/growth.rst",
            category="{set}",
            subcategory="set figures",
            labels={"figure": "growth with distance"},
        ),
    params:
        source=script_source("render_set_figure"),
        logs=lambda w: run_logs(w.set),
        kind="growth",
        title=lambda w: config["experiment_sets"][w.set]["title"],
    log:
        "logs/render_growth_figure/{set}.log",
    benchmark:
        "data/benchmarks/render_growth_figure/{set}.tsv"
    script:
        "../scripts/render_set_figure.py"


rule render_cloud_polar_figure:
    input:
        logs=polar_logs,
    output:
        report(
            "reports/figures/{set}/cloud_polar.png",
            caption="../report/cloud_polar.rst",
            category="{set}",
            subcategory="set figures",
            labels={"figure": "Cartesian and polar views"},
        ),
    params:
        source=script_source("render_set_figure"),
        logs=polar_logs,
        kind="cloud_polar",
        title=lambda w: config["experiment_sets"][w.set]["title"],
    log:
        "logs/render_cloud_polar_figure/{set}.log",
    benchmark:
        "data/benchmarks/render_cloud_polar_figure/{set}.tsv"
    script:
        "../scripts/render_set_figure.py"


rule render_drives_figure:
    input:
        runs=lambda w: runs_made(w.set),
    output:
        report(
            "reports/figures/{set}/drives.png",
            caption="../report/drives.rst",
            category="{set}",
            subcategory="set figures",
            labels={"figure": "sigma along and across per drive"},
        ),
    params:
        source=script_source("render_set_figure"),
        logs=lambda w: run_logs(w.set),
        kind="drives",
        title=lambda w: config["experiment_sets"][w.set]["title"],
    log:
        "logs/render_drives_figure/{set}.log",
    benchmark:
        "data/benchmarks/render_drives_figure/{set}.tsv"
    script:
        "../scripts/render_set_figure.py"


# A set of more runs than report.summary_above: summary views from its table alone (axes, sensitivity
# indices, partial dependence, response surfaces) instead of per-run figures.
rule summarize_sweep:
    input:
        table="reports/tables/{set}.csv",
    output:
        summary="reports/tables/{set}.sweep.json",
        heatmaps=report(
            "reports/figures/{set}/sweep_heatmaps.png",
            caption="../report/sweep.rst",
            category="{set}",
            subcategory="set figures",
            labels={"figure": "response surfaces"},
        ),
        dependence=report(
            "reports/figures/{set}/sweep_dependence.png",
            caption="../report/sweep.rst",
            category="{set}",
            subcategory="set figures",
            labels={"figure": "partial dependence"},
        ),
    params:
        source=script_source("summarize_sweep"),
    log:
        "logs/summarize_sweep/{set}.log",
    benchmark:
        "data/benchmarks/summarize_sweep/{set}.tsv"
    script:
        "../scripts/summarize_sweep.py"
