"""Sphinx configuration of the setobs-bench documentation site (``make docs``).

The observer pages (``observers/``) and the API reference (``api/``) are generated at build
time from the registry and the packages by ``_ext/setobs_docs.py``; every code example of the
site is executed by ``tests/test_docs.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
sys.path.insert(0, str(HERE.parent))  # the checkout's packages (an installed copy also works)

project = "setobs-bench"
author = "setobs-bench contributors"
copyright = "setobs-bench contributors, BSD-3-Clause"  # noqa: A001

try:
    from importlib.metadata import version as _version

    release = _version("setobs-bench")
except Exception:  # noqa: BLE001 - building from a checkout that is not installed
    release = "unknown"

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.viewcode",
    "numpydoc",
    "mathml",
    "setobs_docs",
]

# no network at build or view time: the equations of the docstrings (``.. math::``, ``:math:``)
# are converted to MathML at build time by docutils' converter (_ext/mathml.py) and typeset by
# the browser itself, so no MathJax (Sphinx's default, loaded from a CDN) is fetched
html_math_renderer = "mathml"
html_theme = "alabaster"
html_theme_options = {"page_width": "1200px", "sidebar_width": "260px",
                      "description": "benchmark harness for guaranteed state estimators"}
html_title = f"setobs-bench {release}"
html_static_path: list[str] = []
html_show_sourcelink = False
exclude_patterns = ["_build"]
root_doc = "index"
nitpicky = False

autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": False}
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # the numpydoc sections carry the types
autodoc_mock_imports: list[str] = []
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks: set[str] = set()
numpydoc_xref_param_type = False

# our docstrings name an observer's options in an "Options" section, which setobs_docs hands
# to numpydoc as "Other Parameters"; numpydoc's signature pass still parses the raw docstring
import warnings  # noqa: E402

warnings.filterwarnings("ignore", message="Unknown section Options", category=UserWarning)
