# One run → one MCAP log (byte-reproducible) + its wall-clock timings (pose_uncertainty.cli.job).
# runs_per_job = 1: one job per run (rule simulate_run); above 1: one job per chunk of a set's runs
# (rules simulate_chunk_<set>_<i>, one process each, the same logs byte for byte, and one timings file
# for the chunk's runs: half the files for Snakemake to track). A log is requested by its file either
# way; in a chunk, its chunk's job makes it.

if RUNS_PER_JOB == 1:

    rule simulate_run:
        output:
            log="data/runs/{set}/{run}.mcap",
            timings="data/runs/{set}/{run}.timings.json",
        params:
            config=as_json(run_config),
            # the code that computes a run: a change to it reruns every simulation (the logs record it)
            source=SOURCE_JOB,
        resources:
            # what the run estimates it needs (a cluster job's --mem and --time)
            mem_mb=lambda wc: run_resources(wc)["mem_mb"],
            runtime=lambda wc: run_resources(wc)["runtime"],
        log:
            "logs/simulate_run/{set}/{run}.log",
        benchmark:
            "data/benchmarks/simulate_run/{set}/{run}.tsv"
        shell:
            "{JOB} simulate-run {params.config:q} {output.log:q} {output.timings:q} 2> {log:q}"


# One rule per chunk (its outputs are its runs' files, which no wildcard can spell), of dead-reckoning runs
# and of localization runs alike. Its params are its runs' configurations: a changed run changes its
# chunk's params alone, so only that chunk reruns.
for _kind, _prefix, _all_chunks in (("run", "simulate_chunk", CHUNKS), ("localization", "simulate_localization_chunk", LOC_CHUNKS)):
    for _set, _set_chunks in _all_chunks.items():
        for _i, _runs in enumerate(_set_chunks):
            _logs = [r.path for r in _runs] if _kind == "run" else [localization_log(_set, r.id) for r in _runs]
            _timings = chunk_timings(_set, _i, localization=_kind == "localization")

            rule:
                name:
                    f"{_prefix}_{_set}_{_i}"
                output:
                    # first: what the readers of a chunked set wait for (common.smk, runs_made)
                    timings=_timings,
                    logs=_logs,
                params:
                    spec=chunk_job_spec(_runs, _logs, _timings, _kind),
                    source=SOURCE_JOB,
                resources:
                    **chunk_resources(_runs, _kind),
                log:
                    f"logs/{_prefix}/{_set}/{_i}.log",
                benchmark:
                    f"data/benchmarks/{_prefix}/{_set}/{_i}.tsv"
                shell:
                    "{JOB} simulate-chunk {params.spec:q} 2> {log:q}"
