# One run → one MCAP log (byte-reproducible) + its wall-clock timings.


rule simulate_run:
    output:
        log="data/runs/{set}/{run}.mcap",
        timings="data/runs/{set}/{run}.timings.json",
    params:
        config=run_config,
        # the code that computes a run: a change to it reruns every simulation (the logs record it)
        source=SOURCE_RUNS,
    log:
        "logs/simulate_run/{set}/{run}.log",
    benchmark:
        "data/benchmarks/simulate_run/{set}/{run}.tsv"
    script:
        "../scripts/simulate_run.py"
