"""logs layer.

Each run kind has its own log module; :func:`pose_uncertainty.logs.runlog.open_run` reads
every kind, importing the localization runs' reader (:mod:`.localization_log`) the first time it
meets such a log (:func:`pose_uncertainty.logs.runlog.log_kind`), so a job that writes one
dead-reckoning run does not pay for importing the localization code.
"""
