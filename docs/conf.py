"""Sphinx configuration: the API reference from the docstrings, plus the guides.

Built in CI with warnings as errors (``.ci/run``); no network (no intersphinx), no
notebooks executed.
"""

from __future__ import annotations

import os
import sys

# Document this checkout's package, not whichever one happens to be installed.
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "src"))
# attribute_docs: constants' docstrings where the package re-exports them
sys.path.insert(0, os.path.join(HERE, "_ext"))

import panda_py  # noqa: E402

project = "panda-py (pure Python)"
author = "panda-py-pure contributors"
copyright = "the panda-py-pure contributors"
release = panda_py.__version__
version = release

extensions = [
    "sphinx.ext.autodoc",
    "myst_parser",
    "attribute_docs",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build"]

# The API reference: members come from each module's __all__; ``tests/test_docs.py``
# checks that every public name has a docstring and a directive here.
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_class_signature = "mixed"
autoclass_content = "class"
# float64 arrays: the alias, not its expansion ndarray[tuple[Any, ...], dtype[float64]]
autodoc_type_aliases = {"FloatArray": "FloatArray", "Vec7": "Vec7"}

myst_enable_extensions = ["colon_fence"]
myst_heading_anchors = 3

html_theme = "furo"
html_title = f"panda-py (pure Python) {release}"
html_static_path: list[str] = []
