"""On-demand speed benchmarks; results go to benchmarks/results/*.json (git-ignored)."""
