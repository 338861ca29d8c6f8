#!/usr/bin/env bash
# Run the pipeline in the current directory so that a killed run recovers by itself
# (what `make report` and `make quick` call):
#
#   workflow/run-locked.sh .venv/bin/snakemake --profile workflow/profiles/default ...
#
# 1. Take an exclusive flock on .snakemake/run.flock, held for the whole run (snakemake
#    inherits the file descriptor through exec; the kernel releases it when snakemake exits,
#    however it dies). Held by another run: print one line, exit 75.
# 2. With the flock held and no snakemake process or job script of another run working in
#    this directory, a Snakemake lock (.snakemake/locks/*) can only have been left by a
#    killed run: remove it, and the temporary files (.<name>.*.part) its writers left in
#    data/ and reports/.
# 3. exec snakemake; the profiles' rerun-incomplete redoes the jobs the kill interrupted.
set -euo pipefail

if [ "$#" -lt 1 ]; then
  echo "usage: $0 SNAKEMAKE [ARGS...]" >&2
  exit 64
fi

state=.snakemake
mkdir -p "$state"
exec 9>>"$state/run.flock"
if ! flock --nonblock 9; then
  holder=$(cat "$state/run.pid" 2>/dev/null || true)
  echo "run-locked: another pipeline run${holder:+ (pid $holder)} is active in $PWD; wait for it to finish or stop it, then rerun" >&2
  exit 75
fi
echo "$$" >"$state/run.pid"  # exec keeps this pid for snakemake

# Another snakemake started by hand (without this wrapper) in this directory, or a job (a script
# job, or a `python -m pose_uncertainty.cli.job` command) that outlived its killed snakemake
# (kill -9 of snakemake alone)?
others=""
for proc in /proc/[0-9]*; do
  pid=${proc#/proc/}
  [ "$pid" = "$$" ] && continue
  [ "$(readlink "$proc/cwd" 2>/dev/null)" = "$PWD" ] || continue
  argv=()
  mapfile -d '' -t argv <"$proc/cmdline" 2>/dev/null || continue
  for a in "${argv[@]:0:4}"; do
    # the snakemake entry point, `python -m snakemake`, a job's script or a job command
    if [ "${a##*/}" = snakemake ] || [[ "$a" == *.snakemake/scripts/* ]] || [ "$a" = pose_uncertainty.cli.job ]; then
      others="$others $pid"
      break
    fi
  done
done
if [ -n "$others" ]; then
  echo "run-locked: another snakemake run or its jobs are still working in $PWD (pid$others); wait for them to finish or stop them, then rerun" >&2
  exit 75
fi

if compgen -G "$state/locks/*" >/dev/null; then
  echo "run-locked: removing the Snakemake lock left by an interrupted run" >&2
  rm -f "$state"/locks/*
fi
for d in data reports; do
  if [ -d "$d" ]; then
    find "$d" -type f -name '.*.part' -print -delete | sed 's/^/run-locked: removed the partial file /' >&2
  fi
done

exec "$@"
