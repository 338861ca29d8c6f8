"""Sphinx configuration of the pose-uncertainty documentation (``make docs``).

Everything is offline: MathJax is served from the ``sphinx-mathjax-offline`` wheel, the theme
loads no web fonts or analytics, and the notebook is executed at build time on this machine.
The reference pages are generated from the code (``_ext/pu_reference.py``): the API by
autosummary, the CLI from the argument parser, the config keys from the key tables and the
pipeline schema, the measures from their registry, the log topics and schemas from ``records``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
sys.path.insert(0, str(HERE.parent / "src"))
os.environ.setdefault("MPLBACKEND", "Agg")

import pose_uncertainty

# The exploration notebook lives in notebooks/ (its one copy); the build renders it, executed,
# from a copy in the tutorials (git-ignored).
NOTEBOOK = HERE.parent / "notebooks" / "explore_runs.ipynb"
_copy = HERE / "tutorials" / "explore_runs.ipynb"
if not _copy.exists() or _copy.read_bytes() != NOTEBOOK.read_bytes():
    _copy.write_bytes(NOTEBOOK.read_bytes())

project = "pose-uncertainty"
author = "the pose-uncertainty developers"
copyright = "the pose-uncertainty developers"
version = release = pose_uncertainty.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.doctest",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",  # MathJax 3 copied into _static/mathjax (no CDN)
    "myst_nb",
    "pu_reference",
]

# --- sources -----------------------------------------------------------------------------------
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "**.ipynb_checkpoints", "Thumbs.db", ".DS_Store"]
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

# the exploration notebook, executed at build time (it writes its own small logs)
nb_execution_mode = "force"
nb_execution_timeout = 300
nb_execution_raise_on_error = True
nb_execution_show_tb = True

# --- API reference -------------------------------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = False
autosummary_ignore_module_all = True  # every public name, also those a docstring refers to
autodoc_default_options = {"members": True, "undoc-members": True, "ignore-module-all": True}
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # the numpy docstrings state types, shapes and units
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_use_param = False  # types as text: "ndarray, shape (N, 3)" is not a cross-reference
napoleon_use_keyword = False
napoleon_use_ivar = True
# A type in a numpy docstring ("ndarray, shape (N, 3)", "float [m]") is text, not a reference:
# leave unresolved class names alone unless they name this package. Every other reference
# (:func:, :mod:, :data:, :doc:, a class of the package) must resolve, or the build fails.
nitpicky = True
# A "Raises" entry is prose too ("ValueError — one line naming the key"), and a private helper
# (``_splat``) a docstring mentions is deliberately not documented.
nitpick_ignore_regex = [
    ("py:class", r"(?!pose_uncertainty\.).*"),
    ("py:exc", r"(?!pose_uncertainty\.).*"),
    ("py:.*", r"(.*\.)?_[A-Za-z]\w*"),
]
# "shape" in such a type matches several attributes named shape: not a reference either
suppress_warnings = ["autosummary.import_cycle", "ref.python"]

# --- HTML ----------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = "pose-uncertainty"
html_static_path = ["_static"]
html_css_files = ["custom.css"]
html_context = {"default_mode": "auto"}  # light or dark as the reader's system is (the theme logs an error without it)
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": [],
}
html_show_sourcelink = False
html_last_updated_fmt = None
