"""logs layer.

Importing it registers the localization runs' log kind with
:func:`pose_uncertainty.logs.runlog.open_run` (:mod:`.localization_log`), so that every
reader of run logs also reads localization logs.
"""

from . import (
    localization_log as localization_log,  # registers LOG_KINDS["pose-uncertainty-localization"]
)
