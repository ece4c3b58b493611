"""patrolling_sim: multi-robot patrolling simulation and benchmarking.

Subpackages, by layer from the bottom up (a layer imports only layers below it; the order is
checked by the import contracts in ``.importlinter`` and explained in docs/architecture.md):

``common`` -- ``model`` -- ``planning`` -- ``algorithms`` -- ``startpos`` -- ``monitor`` --
``scenarios`` -- ``agent`` -- ``extraction`` -- ``experiment`` -- ``graphsim`` -- ``report``
-- ``runner`` | ``ros`` -- ``campaign``.

Everything but ``ros`` and ``runner`` imports no ROS module and runs without a master.
"""
__version__ = "0.1.0"
