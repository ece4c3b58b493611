"""Generate the roslaunch file of one experiment from its configuration.

roslaunch cannot loop over N robots, so the runner writes one file per run and keeps it in
the results folder (``<prefix>_experiment.launch``) so that the run can be reproduced with
plain ``roslaunch``. The file composes:

- global parameters (``/use_sim_time``, ``/goal_reached_wait``, ``/communication_delay``,
  ``/lost_message_rate``, ``/navigation_module``, ``/initial_positions``, ``/initial_pos``,
  and the scenario: ``/comm_model`` (communication model spec), ``/attrition`` (the explicit
  failure schedule ``ROBOT@T[+REPAIR],...``, the random model already drawn from the seed),
  ``/scenario_seed``; docs/scenarios.md),
- the simulator (``patrol_stage2d/launch/stage2d.launch``),
- one map server (``spqrel_nav_lite`` map_server publishing ``/map``),
- per robot the package's ``launch/robot.launch`` (localisation + navigation in namespace
  ``robot_i``; with ``processes: shared`` both in one ``robot_nav`` process; with ``pooled[:K]`` and
  ``pooled-separate[:K]`` only the robot's parameters, its navigation being hosted by one of
  K ``nav_host`` processes, see :func:`_nav_hosts`); every navigation process gets the plan
  store's folder (``plan_store``: ``$PATROLLING_SIM_PLAN_STORE``, default
  ``~/.cache/patrolling_sim/plan_store``, ``none`` for none; docs/navigation.md),
- the monitor and the N agents (``processes: shared`` or ``pooled``: one ``patrol_agents``
  process hosting all of them; ``separate`` or ``pooled-separate``: one ``patrol_agent`` node
  per robot, as the original),
- optionally rviz with the package's ``launch/patrol.rviz``.

With ``nav: abstract`` the simulator, map server and per-robot navigation are replaced by
one ``abstract_world`` node (straight-line motion, see :func:`_abstract_world`).
"""
import math
import os
import shlex
from xml.sax.saxutils import quoteattr

from spqrel_nav_lite import plan_store

from patrolling_sim.common import paths
from patrolling_sim.agent.factory import agent_seed
from patrolling_sim.model.graph import load_graph
from patrolling_sim.experiment.validation import process_layout, resolve_pace


#: ``nav`` value of the abstract world: no simulator, map server, localisation or move_base;
#: one ``abstract_world`` node (src/patrolling_sim/tools/abstract_world.py) moves every robot
#: in straight lines at 1 m/s and publishes /clock (docs/abstract_world.md)
ABSTRACT_NAV = "abstract"
#: wall s the abstract world's clock stands still at its first step until every agent has
#: announced itself ready (its ``~start_wait``, docs/abstract_world.md, "Start hold"): GO
#: then comes at the same sim time in every run. Generous, for large teams on a busy machine;
#: a hold that reaches it only lets the clock run as it would without the hold.
START_WAIT = 120.0


def status_topic(cfg):
    """The topic with the run's sim time and pace (JSON with ``sim_time`` and ``rtf``)."""
    return "/abstract_world/status" if cfg.nav == ABSTRACT_NAV else "/stage2d/status"


def _abstract_world(a, cfg, n):
    a("  <!-- abstract world: /clock and every robot's move_base (straight lines, 1 m/s) -->")
    a('  <node pkg="patrolling_sim" type="abstract_world.py" name="abstract_world" '
      'required="true" output="log">')
    a(f'    <param name="team_size" value="{n}"/>')
    a(f'    <param name="speedup" value="{_num(resolve_pace(cfg.speedup, cfg.nav))}"/>')
    a(f'    <param name="start_wait" value="{_num(START_WAIT)}"/>')
    if cfg.scenario()[0].name == "range":
        # the range model judges links from the robots' poses on /positions, which the
        # agents publish from move_base feedback
        a('    <param name="feedback" value="true"/>')
    a("  </node>")
    a("")


def _nav_hosts(a, cfg, n, hosts, yaml_path, n_vertices, store):
    """``hosts`` nav_host processes, each hosting the localiser + move_base of a contiguous
    block of robots (sizes differ by at most one). They run in namespace ``/nav_pool`` whose
    ``actionlib_status_frequency`` matches the per-robot nodes' (1 Hz); their plan caches
    hold a navigation function for every vertex of the patrol graph (the patrol goals), read
    from and written to the plan store ``store`` (None: none) shared with the other processes
    and later runs."""
    a("  <!-- navigation: localiser + move_base of every robot in nav_host processes (each")
    a("       robot keeps its robot_i topics, move_base action, services, frames, params) -->")
    a('  <group ns="nav_pool">')
    a('    <param name="actionlib_status_frequency" value="1.0"/>')
    for k in range(hosts):
        lo, hi = k * n // hosts, (k + 1) * n // hosts
        robots = " ".join(f"robot_{i}" for i in range(lo, hi))
        a(f'    <node pkg="spqrel_nav_lite" type="nav_host" name="nav_host_{k}" output="log">')
        a(f"      <param name=\"robots\" value={_attr(robots)}/>")
        a(f"      <param name=\"localization\" value={_attr(cfg.loc)}/>")
        a(f"      <param name=\"map_yaml\" value={_attr(yaml_path)}/>")
        a(f"      <param name=\"plan_cache_goals\" value=\"{int(n_vertices)}\"/>")
        if store:
            a(f"      <param name=\"plan_store\" value={_attr(store)}/>")
        a("    </node>")
    a("  </group>")
    a("")


def _attr(v):
    return quoteattr(str(v))


def _num(v):
    return repr(float(v))


def graph_drawing(graph_path):
    """The patrol graph as the simulator draws it: ("x y x y ..." in metres, "u v u v ...")."""
    G = load_graph(graph_path, warn=False)
    xy = " ".join(f"{G.nodes[v]['pos'][0]:.4f} {G.nodes[v]['pos'][1]:.4f}" for v in sorted(G.nodes))
    edges = sorted({(min(u, w), max(u, w)) for u, w in G.edges()})
    return xy, " ".join(f"{u} {w}" for u, w in edges)


def scenario_params(cfg):
    """The scenario's global ROS parameters: ``/comm_model`` (the model's canonical spec),
    ``/attrition`` (explicit schedule, so every node fails the same robots at the same
    times), ``/scenario_seed``."""
    model, schedule = cfg.scenario()
    # repr: the times round-trip exactly (a drawn random time has more digits than %g keeps)
    explicit = ",".join(f"{f.robot}@{f.t!r}" + ("" if f.repair is None else f"+{f.repair!r}")
                        for f in schedule) or "none"
    return {"/comm_model": model.describe(), "/attrition": explicit,
            "/scenario_seed": int(cfg.seed)}


def generate_launch(cfg, positions, run_prefix, snapshot_dir=None, yaw=math.pi / 2,
                    rviz_config=None):
    """Return the launch XML (str) for ``cfg`` with robots at ``positions`` [(x, y)].

    Args:
        cfg: validated :class:`ExperimentConfig`.
        positions: start positions, one per robot.
        run_prefix: the result-file prefix the monitor must use (``.../<date>``), so every
            file of the run shares it.
        snapshot_dir: if set, the simulator saves periodic PNG snapshots there.
        rviz_config: rviz config file for ``cfg.rviz`` (default the package's
            ``launch/patrol.rviz``).
    """
    agents, nav_mode, hosts = process_layout(cfg.processes, cfg.robots)
    # navigation functions shared by the navigation processes and kept for later runs
    # (spqrel_nav_lite.plan_store; $PATROLLING_SIM_PLAN_STORE=none turns it off)
    store = plan_store.default_root()
    yaml_path, graph_path = (os.path.abspath(p) for p in paths.map_files(cfg.map))
    n = cfg.robots
    poses = " ".join(f"{x:.4f} {y:.4f} {yaw:.4f}" for x, y in positions)
    flat = ", ".join(f"{v:.4f}" for p in positions for v in p)
    L = []
    a = L.append
    a('<?xml version="1.0"?>')
    a("<!-- Generated by scripts/start_experiments.py. Reproduce with: roslaunch THIS_FILE -->")
    a("<!-- " + " ".join(f"{k}={v}" for k, v in cfg.to_dict().items()).replace("--", "-") + " -->")
    a("<launch>")
    _global_params(a, cfg, flat)
    if cfg.nav == ABSTRACT_NAV:
        _abstract_world(a, cfg, n)
    else:
        n_vertices = _simulator(a, cfg, yaml_path, graph_path, poses, snapshot_dir)
        # roslaunch splits args as a shell would: the quoted path keeps its spaces
        a('  <node pkg="spqrel_nav_lite" type="map_server" name="map_server" '
          f'args={_attr(shlex.quote(yaml_path))} output="log"/>')
        a("")
        robot_launch = "$(find patrolling_sim)/launch/robot.launch"
        _robots(a, cfg, positions, yaw, robot_launch, yaml_path, nav_mode, store)
        if nav_mode == "pooled" and cfg.nav != "ros":
            _nav_hosts(a, cfg, n, hosts, yaml_path, n_vertices, store)
    _monitor(a, cfg, n, run_prefix)
    _agents(a, cfg, n, agents)
    if cfg.rviz:
        a("")
        a('  <node pkg="rviz" type="rviz" name="rviz" '
          f'args={_attr("-d " + (rviz_config or "$(find patrolling_sim)/launch/patrol.rviz"))} '
          'output="log"/>')
    a("</launch>")
    return "\n".join(L) + "\n"


def _global_params(a, cfg, flat):
    """Append the global parameters (module docstring), ``flat`` being the start positions
    as "x0, y0, x1, ..." for ``/initial_pos``, and a blank line."""
    a('  <param name="/use_sim_time" value="true"/>')
    a(f'  <param name="/goal_reached_wait" value="{_num(cfg.gwait)}"/>')
    a(f'  <param name="/communication_delay" value="{_num(cfg.comm_delay)}"/>')
    a(f'  <param name="/lost_message_rate" value="{_num(cfg.loss)}"/>')
    a(f'  <param name="/navigation_module" value={_attr(cfg.nav)}/>')
    for name, value in scenario_params(cfg).items():
        kind = "str" if isinstance(value, str) else "int"
        a(f'  <param name="{name}" type="{kind}" value={_attr(value)}/>')
    a(f'  <param name="/localization_module" value={_attr(cfg.loc)}/>')
    a(f'  <param name="/initial_positions" value={_attr(cfg.initpos)}/>')
    a(f'  <rosparam param="/initial_pos">[{flat}]</rosparam>')
    a("")


def _simulator(a, cfg, yaml_path, graph_path, poses, snapshot_dir):
    """Append the simulator's include (robots at ``poses``, "x y yaw ..."; the patrol graph
    drawn; snapshots in ``snapshot_dir`` if set) and a blank line. Returns the patrol
    graph's vertex count."""
    a("  <!-- simulator: all robots, laser, odometry, ground truth, tf, /clock -->")
    a('  <include file="$(find patrol_stage2d)/launch/stage2d.launch">')
    a(f"    <arg name=\"map\" value={_attr(yaml_path)}/>")
    a(f"    <arg name=\"poses\" value={_attr(poses)}/>")
    a(f"    <arg name=\"speedup\" value=\"{_num(resolve_pace(cfg.speedup, cfg.nav))}\"/>")
    a(f"    <arg name=\"gui\" value=\"{str(cfg.gui_sim).lower()}\"/>")
    graph_xy, graph_edges = graph_drawing(graph_path)
    a(f"    <arg name=\"graph_vertices\" value={_attr(graph_xy)}/>")
    a(f"    <arg name=\"graph_edges\" value={_attr(graph_edges)}/>")
    a(f"    <arg name=\"seed\" value=\"{int(cfg.seed)}\"/>")
    if snapshot_dir:
        a(f"    <arg name=\"snapshot_dir\" value={_attr(snapshot_dir)}/>")
        a(f"    <arg name=\"snapshot_period\" value=\"{_num(cfg.record_period)}\"/>")
    a("  </include>")
    a("")
    return len(graph_xy.split()) // 2


def _robots(a, cfg, positions, yaw, robot_launch, yaml_path, nav_mode, store):
    """Append one include of ``robot_launch`` per robot (its start pose; combined
    localisation + navigation for ``nav_mode`` "robot_nav", no navigation nodes for
    "pooled"), each followed by its move_base's plan store unless there is none, navigation
    is pooled or ROS's; then a blank line."""
    for i, (x, y) in enumerate(positions):
        a(f'  <include file={_attr(robot_launch)}>')
        a(f'    <arg name="robotname" value="robot_{i}"/>')
        a(f'    <arg name="mapname" value={_attr(cfg.map_name)}/>')
        a(f'    <arg name="map_yaml" value={_attr(yaml_path)}/>')
        a(f'    <arg name="x" value="{x:.4f}"/>')
        a(f'    <arg name="y" value="{y:.4f}"/>')
        a(f'    <arg name="yaw" value="{yaw:.4f}"/>')
        a(f'    <arg name="localization" value={_attr(cfg.loc)}/>')
        a(f'    <arg name="navigation" value={_attr(cfg.nav)}/>')
        a(f'    <arg name="combined" value="{str(nav_mode == "robot_nav").lower()}"/>')
        if nav_mode == "pooled":
            a('    <arg name="nav_nodes" value="false"/>')
        a("  </include>")
        if store and nav_mode != "pooled" and cfg.nav != "ros":
            a(f'  <param name="robot_{i}/move_base/plan_store" value={_attr(store)}/>')
    a("")


def _monitor(a, cfg, n, run_prefix):
    """Append the monitor node (required: the run ends when it exits) for a team of ``n``
    writing its files under ``run_prefix``."""
    a("  <!-- monitor: ends the run (timeout / cycles / dead robot / abort); required, so")
    a("       roslaunch shuts everything down when it exits after writing its files -->")
    a('  <node pkg="patrolling_sim" type="monitor" name="monitor" required="true" output="log"')
    a(f"        args={_attr(f'{cfg.map_name} {cfg.alg} {n}')}>")
    a(f'    <param name="map" value={_attr(cfg.map)}/>')
    a(f'    <param name="results_dir" value={_attr(os.path.abspath(cfg.results_dir))}/>')
    a(f'    <param name="run_prefix" value={_attr(run_prefix)}/>')
    a(f'    <param name="timeout" value="{_num(cfg.timeout)}"/>')
    a(f'    <param name="cycles" value="{int(cfg.cycles)}"/>')
    a(f'    <param name="dead_robot_timeout" value="{_num(cfg.dead_robot_timeout)}"/>')
    a(f'    <param name="map_label" value={_attr(cfg.result_name)}/>')
    a(f'    <param name="attrition_spec" type="str" value={_attr(cfg.attrition)}/>')
    a("  </node>")


def _agents(a, cfg, n, agents):
    """Append the ``n`` agents: one ``patrol_agents`` process hosting all of them if
    ``agents`` is "shared", else one ``patrol_agent`` node per robot; agent i's seed is
    ``agent_seed(cfg.seed, i)``."""
    if agents == "shared":
        # every agent in one process: the same PatrolAgent objects and topics, but each
        # /positions and /results message is received once instead of N times
        a('  <node pkg="patrolling_sim" type="patrol_agents" name="patrol_agents" '
          f'output="log" args={_attr(f"{cfg.map_name} 0-{n - 1}")}>')
        a(f'    <param name="algorithm" value={_attr(cfg.alg)}/>')
        a(f'    <param name="map" value={_attr(cfg.map)}/>')
        a(f'    <param name="team_size" value="{n}"/>')
        # agent i of patrol_agents gets ~seed + i: agent_seed(seed, i), as in graph mode
        a(f'    <param name="seed" value="{agent_seed(cfg.seed, 0)}"/>')
        _strategy_params(a, cfg)
        a("  </node>")
    else:
        for i in range(n):
            a(f'  <node pkg="patrolling_sim" type="patrol_agent" name="patrol_robot{i}" '
              f'output="log" args={_attr(f"{cfg.map_name} {i}")}>')
            a(f'    <param name="algorithm" value={_attr(cfg.alg)}/>')
            a(f'    <param name="map" value={_attr(cfg.map)}/>')
            a(f'    <param name="team_size" value="{n}"/>')
            a(f'    <param name="seed" value="{agent_seed(cfg.seed, i)}"/>')
            _strategy_params(a, cfg)
            a("  </node>")


def _strategy_params(a, cfg):
    """Append an agent node's ``~params`` (the strategy's params, e.g. the policy file)."""
    for key, value in sorted(cfg.strategy_params().items()):
        a(f'    <param name="params/{key}" type="str" value={_attr(str(value))}/>')
