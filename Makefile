# The two commands of the README: `make report` and `make test`.
# Both create .venv from environment.lock when it is missing (or the lock changed),
# install the package itself without dependencies, then run.

PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
CORES  ?= all
# holds a flock for the whole run, clears what a killed run left (workflow/run-locked.sh)
LOCKED := workflow/run-locked.sh
# Every pipeline job is a new interpreter that imports the package: its bytecode is compiled once
# here, so that no job compiles ~30 000 lines again (0.15 s a job where PYTHONDONTWRITEBYTECODE is
# set, as in many containers); ms when the files are up to date.
COMPILE := $(BIN)/python -m compileall -q src

.PHONY: report test quick bench bench-report bench-regenerate bench-sweep lint venv lock clean slurm-up slurm-down docs

venv: $(STAMP)

$(STAMP): environment.lock pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --require-hashes --no-deps -r environment.lock
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation -e .
	@touch $@

report: $(STAMP)
	$(COMPILE)
	$(LOCKED) $(BIN)/snakemake --profile workflow/profiles/default --cores $(CORES)

quick: $(STAMP)
	$(COMPILE)
	$(LOCKED) $(BIN)/snakemake --profile workflow/profiles/default --cores $(CORES) --configfile config/quick.yaml

# the whole suite on TEST_PROCESSES processes (pytest-xdist; a module's tests on one, tests/conftest.py)
# (the 25 longest test phases listed at the end: where the time goes, in CI logs too)
TEST_PROCESSES ?= 2

test: $(STAMP)
	$(COMPILE)
	$(BIN)/python -m pytest -n $(TEST_PROCESSES) --dist loadscope --durations=25

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks workflow/scripts
	$(BIN)/mypy

bench: $(STAMP)
	$(BIN)/python -m benchmarks

# the report in a browser: Lighthouse (npm, pinned in benchmarks/lighthouse/package-lock.json) with Debian's
# chromium on reports/comparison.html served from 127.0.0.1 -> benchmarks/results/report.json
# (ARGS="--gzip --name report-gzip": served gzip-compressed, as a web host would)
bench-report: $(STAMP)
	npm ci --prefix benchmarks/lighthouse --no-audit --no-fund --silent
	CHROME_PATH=$${CHROME_PATH:-/usr/bin/chromium} $(BIN)/python -m benchmarks.report_lighthouse $(REPORT) $(ARGS)

# a full regeneration in a fresh clone: times and sizes -> benchmarks/results/regenerate.json
bench-regenerate: $(STAMP)
	$(BIN)/python -m benchmarks.regenerate

# a large sweep batched (runs_per_job) against one run per job: DAG build, wall and CPU time, per-run
# overhead, peak memory, report size -> benchmarks/results/sweep.json (ARGS="--runs 500", "--full --dag-only")
bench-sweep: $(STAMP)
	$(BIN)/python -m benchmarks.sweep $(ARGS)

lock:
	uv pip compile requirements.in --python-version 3.11 --python-platform x86_64-unknown-linux-gnu --generate-hashes -o environment.lock

# A single-node SLURM cluster on this machine (root, Debian packages; tests/test_slurm.py uses it):
#   sudo make slurm-up && .venv/bin/snakemake --profile workflow/profiles/slurm-test ...
slurm-up:
	.ci/slurm-up.sh --install

slurm-down:
	.ci/slurm-down.sh

clean:
	rm -rf data reports .snakemake

# the run keys of the pipeline schema, generated from the key tables next to the config dataclasses
schema: $(STAMP)
	$(BIN)/python -m pose_uncertainty.experiments.schema workflow/schemas/config.schema.yaml

# the documentation site → docs/_build/html/index.html (offline; warnings are errors)
docs: $(STAMP)
	$(BIN)/sphinx-build -b html -W --keep-going -n -j 1 docs docs/_build/html
