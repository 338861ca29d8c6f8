"""records layer: the log formats — one interface per kind of log (write / read / summary / verify).

:mod:`.foxglove` builds the messages every kind logs (Foxglove's schemas and ours);
:mod:`.mcap_io` writes and validates the MCAP container they share; :mod:`.formats` holds the
:class:`~.formats.LogFormat` interface, the registry of kinds and :func:`~.formats.open_run`,
which reads every kind, importing a kind's module the first time it meets such a log (so a job
that writes one dead-reckoning run does not pay for importing the localization code).
:mod:`.run` is the dead-reckoning run log (:data:`~.run.RUN_LOG`), :mod:`.localization` the
localization run log (:data:`~.localization.LOCALIZATION_LOG`); :mod:`.reproducibility`
compares two logs under the reproducibility contract.
"""
