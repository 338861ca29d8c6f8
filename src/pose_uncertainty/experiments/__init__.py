"""experiments layer: what a run is and how it executes.

Configuration (:mod:`.config`, :mod:`.drive_config`, :mod:`.config_checks`), sweep expansion
(:mod:`.sweep`), execution of every kind of run — dead reckoning (:mod:`.run`, :mod:`.drive_run`),
localization (:mod:`.localization`), studies (:mod:`.study`) — their cost estimate (:mod:`.cost`)
and progress (:mod:`.progress`). Nothing here writes a log: that is :mod:`pose_uncertainty.records`.
"""
