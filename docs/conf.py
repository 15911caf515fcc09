"""Sphinx configuration of the rventry manual.

Build it (warnings are errors) from the repository root:

    python -m sphinx -W --keep-going -b html docs docs/_build/html

Why Sphinx: the docstrings already carry Sphinx roles (``:class:``, ``:func:``, ``:param:``) that
autodoc renders as they are, and MyST reads the Markdown the manual was written in, so neither the
code nor the existing pages had to be rewritten for the site. The CLI reference is generated from
the argument parsers at each build (``docs/tools/cli_reference.py``).
"""

from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "tools"))

import cli_reference  # noqa: E402
import docstrings  # noqa: E402

from rventry_env import __version__  # noqa: E402

project = "rventry"
author = "the rventry developers"
copyright = "the rventry developers, MIT licence"
release = version = __version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "tools", "results/**/README.md", "README.md"]
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath"]
myst_heading_anchors = 3
# the docstrings' Markdown-style tables and the env docstring's observation table
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True, "ignore-module-all": True}
autodoc_member_order = "bysource"
# a method without a docstring of its own (RvEntryEnv.step) is not given Gymnasium's, written for another format
autodoc_inherit_docstrings = False
autodoc_typehints = "description"
autosummary_generate = True
# JAX, gymnax and rejax are an extra; the pages of the modules that need them are built without them
autodoc_mock_imports = ["jax", "jaxlib", "gymnax", "rejax", "flax", "optax", "distrax", "chex"]
html_theme = "furo"
html_title = f"rventry {release}"
suppress_warnings = ["myst.header"]


def _generate(app) -> None:
    """Write the pages generated from the code before Sphinx reads the sources."""
    from rventry_env.cli import build_parser

    cli_reference.write(build_parser(), DOCS / "reference" / "cli.md")


def setup(app):
    app.connect("builder-inited", _generate)
    app.connect("autodoc-process-docstring", docstrings.process_docstring)
