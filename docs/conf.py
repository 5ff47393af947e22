"""Sphinx configuration of hil's documentation site: Markdown pages (MyST), the furo theme, and pages generated from the
code at build time (the command line from the argparse parsers, :mod:`hil.cli.reference`, the requirement matrix from
the suites' markers; docs/_ext/hil_docs.py)."""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

from hil import __version__  # noqa: E402

project = "hil"
author = "the hil developers"
copyright = "2026, the hil developers"
release = version = __version__

extensions = ["myst_parser", "hil_docs"]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_ext", "Thumbs.db", ".DS_Store"]
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]
html_theme = "furo"
html_title = f"hil {release}"
html_static_path = ["_static"]
