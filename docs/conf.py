"""Sphinx configuration of cpopt's documentation: ``sphinx-build -W -b html docs docs/_build``.

Sphinx rather than MkDocs: the docstrings are numpydoc, which Sphinx's autodoc and numpydoc read
as they are; the problem-file reference is a small Sphinx directive over the pydantic schema
(``_ext/schema_reference.py``); the notebooks render through myst-nb without executing them
(stored without outputs, they need no kernel and no pandoc).
"""

import os
import re
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE / "_ext"))
os.environ.setdefault("MPLBACKEND", "Agg")

import cpopt  # noqa: E402

project = "cpopt"
author = "the cpopt authors"
copyright = "the cpopt authors, MIT licence"
release = version = cpopt.__version__

extensions = [
    "myst_nb",
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "numpydoc",
    "schema_reference",
]

exclude_patterns = ["_build", "**/.ipynb_checkpoints", "notebooks/README.md"]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}

# the notebooks run in the test suite (marker notebook), not at build time
nb_execution_mode = "off"
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3

autodoc_member_order = "bysource"
autodoc_typehints = "none"
# members defined in each module only: a package re-exporting its modules' names (its __all__)
# would otherwise describe them twice
autodoc_default_options = {"members": True, "ignore-module-all": True}
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

html_theme = "pydata_sphinx_theme"
html_title = f"cpopt {release}"
html_theme_options = {
    "navigation_depth": 2,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
}
html_static_path = []

# the Python API reference: one page per layer, written from the package (docs/api/, not in git)
import api_pages  # noqa: E402

api_pages.write(HERE)


def _escape_bars(app, what, name, obj, options, lines):
    """``|gamma|`` in a docstring is an absolute value, not a reST substitution: escape the bars
    outside inline literals."""
    for i, line in enumerate(lines):
        if "|" in line:
            parts = re.split(r"(``.*?``)", line)
            lines[i] = "".join(
                part if part.startswith("``") else re.sub(r"(?<!\\)\|", r"\\|", part)
                for part in parts
            )


def setup(app):
    """Escape the bars of absolute values in docstrings after numpydoc has read them."""
    app.connect("autodoc-process-docstring", _escape_bars, priority=600)
