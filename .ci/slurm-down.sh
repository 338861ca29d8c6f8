#!/usr/bin/env bash
# Stop the single-node SLURM cluster of .ci/slurm-up.sh: slurmd, slurmctld, munged, each by the
# pid in its pid file (never by name), and wait for them to exit.   (make slurm-down)
set -euo pipefail
for pidfile in /run/slurmd.pid /run/slurmctld.pid /run/munge/munged.pid; do
  [ -s "$pidfile" ] || continue
  pid=$(cat "$pidfile")
  if kill -0 "$pid" 2>/dev/null; then
    kill -TERM "$pid"
    for _ in $(seq 30); do
      kill -0 "$pid" 2>/dev/null || break
      sleep 0.5
    done
    if kill -0 "$pid" 2>/dev/null; then
      echo "slurm-down: $pidfile ($pid) did not stop on TERM; killing it" >&2
      kill -KILL "$pid" 2>/dev/null || true
    fi
  fi
  rm -f "$pidfile"
done
echo "slurm-down: stopped" >&2
