"""Sphinx configuration of the API reference (`make docs`; sources generated into build/)."""
project = "patrolling_sim"
author = "patrolling_sim developers"
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.viewcode"]
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True}
autodoc_member_order = "bysource"
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_ivar = True
html_theme = "alabaster"
exclude_patterns = ["_build"]
# the ROS message packages are real imports of the ROS layers; the API reference is built
# without a ROS environment sourced only for the pure layers
nitpicky = False
# the learning environment's PyPI libraries live in .venv/, not in Debian's python3 that builds
# this reference (docs/learning.md): autodoc imports patrolling_sim.envs against stand-ins
autodoc_mock_imports = ["gymnasium", "pettingzoo"]
suppress_warnings = ["app.add_directive"]
