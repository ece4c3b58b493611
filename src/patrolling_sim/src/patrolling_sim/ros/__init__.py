"""ROS glue of patrolling_sim: the PatrolAgent node, the monitor node, the live graph
markers and a stand-in move_base for tests. The pure core (graph, algorithms, monitor
metrics, result files) lives in the parent package and imports no ROS module."""
