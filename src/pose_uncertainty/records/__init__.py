"""records layer: the log formats, one module per kind of run (write / read / summary / verify).

:mod:`.run` holds the dead-reckoning run log and the MCAP machinery every kind shares;
:func:`pose_uncertainty.records.run.open_run` reads every kind, importing the localization runs'
reader (:mod:`.localization`) the first time it meets such a log
(:func:`pose_uncertainty.records.run.log_kind`), so a job that writes one dead-reckoning run does
not pay for importing the localization code. :mod:`.reproducibility` compares two logs under the
reproducibility contract.
"""
