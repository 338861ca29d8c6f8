# Figures: per run (the same functions `pose-uncertainty replay --figures` uses) and per set.


rule render_trajectory_figure:
    input:
        log=rules.simulate_run.output.log,
    output:
        report(
            "reports/figures/{set}/{run}/trajectory.png",
            caption="../report/trajectory.rst",
            category="{set}",
            subcategory="{run}",
            labels={"run": "{run}", "figure": "trajectory and ellipses"},
        ),
    params:
        source=SOURCE_PRESENT,
        kinds=["trajectory"],
    log:
        "logs/render_trajectory_figure/{set}/{run}.log",
    benchmark:
        "data/benchmarks/render_trajectory_figure/{set}/{run}.tsv"
    script:
        "../scripts/render_run_figures.py"


rule render_cloud_figure:
    input:
        log=rules.simulate_run.output.log,
    output:
        report(
            "reports/figures/{set}/{run}/cloud.png",
            caption="../report/cloud.rst",
            category="{set}",
            subcategory="{run}",
            labels={"run": "{run}", "figure": "Monte Carlo cloud"},
        ),
    params:
        source=SOURCE_PRESENT,
        kinds=["cloud"],
    log:
        "logs/render_cloud_figure/{set}/{run}.log",
    benchmark:
        "data/benchmarks/render_cloud_figure/{set}/{run}.tsv"
    script:
        "../scripts/render_run_figures.py"


rule render_map_figure:
    input:
        log=rules.simulate_run.output.log,
    output:
        map=report(
            "reports/figures/{set}/{run}/map_{map}.png",
            caption="../report/map.rst",
            category="{set}",
            subcategory="{run}",
            labels={"run": "{run}", "figure": "probability map {map}"},
        ),
        cloud=report(
            "reports/figures/{set}/{run}/mapcloud_{map}.png",
            caption="../report/map_cloud.rst",
            category="{set}",
            subcategory="{run}",
            labels={"run": "{run}", "figure": "map {map} vs its sampler"},
        ),
    params:
        source=SOURCE_PRESENT,
        kinds=lambda w: [f"map_{w.map}", f"mapcloud_{w.map}"],
    log:
        "logs/render_map_figure/{set}/{run}/{map}.log",
    benchmark:
        "data/benchmarks/render_map_figure/{set}/{run}/{map}.tsv"
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
