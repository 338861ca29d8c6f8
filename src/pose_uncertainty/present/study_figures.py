"""Which study kinds have a figure, and the key the report shows it under.

A table without drawing code, so that the workflow can read it when it is parsed without
importing matplotlib (0.4 s); the functions drawing the figures are those of
:data:`pose_uncertainty.present.pipeline_figures.STUDY_FIGURES`, keyed by the same kinds.
"""

from __future__ import annotations

__all__ = ["STUDY_FIGURE_KEYS"]

#: The figure of a study by the study's kind (a key of pose_uncertainty.analysis.studies.STUDIES):
#: the key the report shows it under (``build_report``'s ``studies_figures``)
STUDY_FIGURE_KEYS: dict[str, str] = {
    "expcoords_regions": "expcoords",
    "umbmark": "umbmark",
}
