# Figures: per run (the same functions `pose-uncertainty replay --figures` uses) and per set.


rule render_run_figures:
    wildcard_constraints:
        run=r"(?![^/]*\.png$)[A-Za-z0-9_.-]+",  # a run's folder, not a set-level figure
    input:
        log=rules.simulate_run.output.log,
    output:
        report(
            directory("reports/figures/{set}/{run}"),
            patterns=["{name}.png"],
            caption="../report/run_figures.rst",
            category="{set}",
            subcategory="{run}",
            labels={"run": "{run}", "figure": "{name}"},
        ),
    params:
        source=SOURCE_PRESENT,
        kinds=lambda w: list(run_figures(w.set, RUN_BY_ID[(w.set, w.run)])),
    log:
        "logs/render_run_figures/{set}/{run}.log",
    benchmark:
        "data/benchmarks/render_run_figures/{set}/{run}.tsv"
    script:
        "../scripts/render_run_figures.py"


rule render_growth_figure:
    input:
        logs=lambda w: run_logs(w.set),
    output:
        report(
            "reports/figures/{set}/growth.png",
            caption="../report/growth.rst",
            category="{set}",
            subcategory="set figures",
            labels={"figure": "growth with distance"},
        ),
    params:
        source=SOURCE_PRESENT,
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
        source=SOURCE_PRESENT,
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
        logs=lambda w: run_logs(w.set),
    output:
        report(
            "reports/figures/{set}/drives.png",
            caption="../report/drives.rst",
            category="{set}",
            subcategory="set figures",
            labels={"figure": "sigma along and across per drive"},
        ),
    params:
        source=SOURCE_PRESENT,
        kind="drives",
        title=lambda w: config["experiment_sets"][w.set]["title"],
    log:
        "logs/render_drives_figure/{set}.log",
    benchmark:
        "data/benchmarks/render_drives_figure/{set}.tsv"
    script:
        "../scripts/render_set_figure.py"
