"""patrolling_sim: multi-robot patrolling simulation and benchmarking.

Subpackages, by layer from the bottom up (a layer imports only layers below it; the order is
checked by the import contracts in ``.importlinter`` and explained in docs/architecture.md):

``common`` -- ``model`` -- ``planning`` -- ``algorithms`` -- ``startpos`` -- ``monitor`` --
``scenarios`` -- ``agent`` -- ``extraction`` -- ``experiment`` -- ``graphsim`` -- ``report``
-- ``runner`` | ``ros`` -- ``campaign``.

Everything but ``ros`` and ``runner`` imports no ROS module and runs without a master.
"""
__version__ = "0.1.0"

# The core reads maps with the navigation package's loader (spqrel_nav_lite.mapio: one
# loader, and spqrel_nav_lite does not depend on this package). A built workspace puts both
# packages on the Python path (devel/setup.bash); the scripts of a source checkout add only
# this package's folder, so the sibling package's source folder is added when it is missing.
try:
    import spqrel_nav_lite  # noqa: F401
except ImportError:
    import os as _os
    import sys as _sys
    _sys.path.append(_os.path.join(_os.path.dirname(_os.path.abspath(__file__)), "..", "..", "..",
                                   "spqrel_nav_lite", "src"))
    import spqrel_nav_lite  # noqa: F401,E402
