"""Drawing settings shared by every layer that draws a figure for the report (the report's own figures in
:mod:`pose_uncertainty.present`, the robot's in :mod:`pose_uncertainty.robot`): matplotlib ``rcParams``
only, as plain data, so that this module imports no plotting library."""

from __future__ import annotations

from typing import Any

__all__ = ["CRISP_RC"]

#: How the report's own figures (set, study and localization-set figures, the robot's) are drawn: text,
#: lines and patches without anti-aliasing. Their PNGs hold 2× the pixels they are shown at: a 1× screen
#: averages each 2 × 2 block, which smooths the edges as anti-aliasing would, and a 2× screen shows them
#: pixel for pixel; the edges' intermediate shades are what made a palette WebP large (the report's 13
#: figures, ~30 % of their bytes; the report is loaded whole before its first paint).
CRISP_RC: dict[str, Any] = {"text.antialiased": False, "lines.antialiased": False, "patch.antialiased": False}
