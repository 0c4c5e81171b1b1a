"""Sphinx configuration of the mbs_envs documentation (Sphinx + MyST, as Gymnasium and DFKI double_pendulum)."""

import os
import sys

sys.path.insert(0, os.path.abspath(".."))
os.environ.setdefault("MBS_ENVS_JIT", "python")  # autodoc imports the package; no kernel compiles for it

project = "mbs_envs"
author = "The mbs_envs developers"
copyright = "2026, The mbs_envs developers"
release = version = "0.2.0"

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.mathjax", "sphinx.ext.viewcode"]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "figures/**", "gallery/**", "Thumbs.db", ".DS_Store"]
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3
suppress_warnings = [
    "myst.header",  # pages keep their own heading levels
    "ref.python",  # numpydoc shapes such as "(..., nv)" name attributes several models share
]

napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_ivar = True  # dataclass fields as fields of the class, not a second description
autodoc_member_order = "bysource"
autodoc_typehints = "none"
autodoc_inherit_docstrings = False  # Gymnasium's own step/reset docs are not ours to render
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True}
default_role = "code"

html_theme = "furo"
html_title = "mbs_envs"
html_static_path = ["_static"]
