"""rviz (ROS 1, rviz 1.14) configuration for watching a patrolling experiment.

rviz configuration files cannot loop over robots, so :func:`make_config` writes one display
group per robot ``robot_i`` (i < ``robots``), enabled for i < ``enabled``:

- ``rviz/PoseWithCovariance`` on ``/robot_i/amcl_pose`` (localisation estimate),
- ``rviz/LaserScan`` on ``/robot_i/base_scan``,
- ``rviz/PoseArray`` on ``/robot_i/particlecloud``,
- ``rviz/Path`` on ``/robot_i/move_base/plan``,

plus the map (``rviz/Map`` on ``/map``) and the patrol graph (``rviz/MarkerArray`` on
``/patrol_graph_markers``). Fixed frame ``map``; top-down orthographic view centred on the
map when a map is given. Displays whose topic has no publisher only show a status warning.
"""
import yaml
from patrolling_sim.common import paths
from spqrel_nav_lite.mapio import load_map

#: one colour per robot (R; G; B), cycling; robot 0 is not blue/red so that its laser stays
#: visible over the graph markers (blue edges, red-to-green vertices)
ROBOT_COLORS = ((255, 140, 0), (0, 190, 190), (210, 0, 210), (30, 170, 30),
                (40, 90, 255), (230, 40, 40), (200, 200, 0), (130, 60, 200))
WINDOW = (1280, 800)
#: Qt dock layout (QMainWindow::saveState) as rviz 1.14 writes it for its stock layout:
#: Displays dock on the left, Views on the right, Time at the bottom, render view between.
#: Without it rviz stacks every panel in the left dock and squeezes the 3D view to nothing.
DOCK_STATE = (
    "000000ff00000000fd00000004000000000000013c0000025ffc0200000008fb0000001200530065006c0065"
    "006300740069006f006e00000001e10000009b0000006400fffffffb0000001e0054006f006f006c00200050"
    "0072006f007000650072007400690065007302000001ed000001df00000185000000a3fb0000001200560069"
    "00650077007300200054006f006f02000001df000002110000018500000122fb000000200054006f006f006c"
    "002000500072006f0070006500720074006900650073003203000002880000011d000002210000017afb0000"
    "00100044006900730070006c00610079007301000000410000025f000000dd00fffffffb0000002000730065"
    "006c0065006300740069006f006e00200062007500660066006500720200000138000000aa0000023a000002"
    "94fb00000014005700690064006500530074006500720065006f02000000e6000000d2000003ee0000030bfb"
    "0000000c004b0069006e0065006300740200000186000001060000030c00000261000000010000010f000002"
    "5ffc0200000003fb0000001e0054006f006f006c002000500072006f00700065007200740069006500730100"
    "000041000000780000000000000000fb0000000a0056006900650077007301000000410000025f000000b000"
    "fffffffb0000001200530065006c0065006300740069006f006e010000025a000000b2000000000000000000"
    "00000200000490000000a9fc0100000001fb0000000a00560069006500770073030000004e00000080000002"
    "e10000019700000003000004420000003efc0100000002fb0000000800540069006d00650100000000000004"
    "420000028900fffffffb0000000800540069006d00650100000000000004500000000000000000000001eb00"
    "00025f00000004000000040000000800000008fc0000000100000002000000010000000a0054006f006f006c"
    "00730100000000ffffffff0000000000000000"
)


def _rgb(c):
    return "%d; %d; %d" % c


def robot_group(i, enabled):
    c = _rgb(ROBOT_COLORS[i % len(ROBOT_COLORS)])
    ns = f"/robot_{i}"
    return {
        "Class": "rviz/Group",
        "Name": f"robot_{i}",
        "Enabled": bool(enabled),
        "Value": bool(enabled),
        "Displays": [
            {"Class": "rviz/PoseWithCovariance", "Name": "Pose (amcl_pose)",
             "Enabled": True, "Value": True, "Topic": f"{ns}/amcl_pose",
             "Unreliable": False, "Queue Size": 10, "Shape": "Arrow", "Color": c,
             "Alpha": 1, "Shaft Length": 0.6, "Shaft Radius": 0.08, "Head Length": 0.3,
             "Head Radius": 0.18,
             "Covariance": {"Value": True,
                            "Position": {"Value": True, "Alpha": 0.3, "Color": c, "Scale": 1},
                            "Orientation": {"Value": False, "Alpha": 0.5, "Color": c,
                                            "Color Style": "Unique", "Frame": "Local",
                                            "Offset": 1, "Scale": 1}}},
            {"Class": "rviz/LaserScan", "Name": "Laser (base_scan)", "Enabled": True,
             "Value": True, "Topic": f"{ns}/base_scan", "Unreliable": False,
             "Queue Size": 10, "Style": "Points", "Size (Pixels)": 3, "Size (m)": 0.05,
             "Color Transformer": "FlatColor", "Color": c, "Alpha": 1,
             "Decay Time": 0, "Selectable": True, "Position Transformer": "XYZ",
             "Use Fixed Frame": True, "Use rainbow": False},
            {"Class": "rviz/PoseArray", "Name": "Particles (particlecloud)", "Enabled": True,
             "Value": True, "Topic": f"{ns}/particlecloud", "Unreliable": False,
             "Queue Size": 10, "Shape": "Arrow (Flat)", "Color": c, "Alpha": 0.6,
             "Arrow Length": 0.3},
            {"Class": "rviz/Path", "Name": "Plan (move_base/plan)", "Enabled": True,
             "Value": True, "Topic": f"{ns}/move_base/plan", "Unreliable": False,
             "Queue Size": 10, "Line Style": "Lines", "Line Width": 0.03, "Color": c,
             "Alpha": 1, "Buffer Length": 1, "Pose Style": "None",
             "Offset": {"X": 0, "Y": 0, "Z": 0}},
        ],
    }


def view_for_extent(extent=None, window=WINDOW):
    """TopDownOrtho view; ``extent`` = (xmin, xmax, ymin, ymax) in metres centres it and
    picks the scale (pixels per metre) so the whole map fits the render area."""
    if extent is None:
        x, y, scale = 0.0, 0.0, 20.0
    else:
        x0, x1, y0, y1 = extent
        x, y = (x0 + x1) / 2.0, (y0 + y1) / 2.0
        render_w, render_h = window[0] - 660, window[1] - 165   # docks, menu, time panel
        scale = 0.95 * min(render_w / max(x1 - x0, 1e-3), render_h / max(y1 - y0, 1e-3))
    return {"Class": "rviz/TopDownOrtho", "Name": "Current View", "Angle": 0,
            "Near Clip Distance": 0.01, "Enable Stereo Rendering": {"Value": False},
            "Invert Z Axis": False, "Target Frame": "<Fixed Frame>",
            "Value": "TopDownOrtho (rviz)", "Scale": round(float(scale), 4),
            "X": round(float(x), 4), "Y": round(float(y), 4)}


def make_config(robots=8, enabled=4, extent=None):
    """Return the rviz configuration as a dict (see module docstring).

    Raises:
        ValueError: robots < 1 or enabled outside 0..robots.
    """
    if robots < 1:
        raise ValueError(f"robots must be >= 1, got {robots}")
    if not 0 <= enabled <= robots:
        raise ValueError(f"enabled must be in 0..{robots}, got {enabled}")
    displays = [
        {"Class": "rviz/Grid", "Name": "Grid (1 m)", "Enabled": False, "Value": False,
         "Cell Size": 1, "Plane Cell Count": 100, "Color": "160; 160; 164", "Alpha": 0.3,
         "Reference Frame": "<Fixed Frame>", "Plane": "XY"},
        {"Class": "rviz/Map", "Name": "Map", "Enabled": True, "Value": True, "Topic": "/map",
         "Alpha": 0.8, "Color Scheme": "map", "Draw Behind": True, "Unreliable": False,
         "Use Timestamp": False},
        {"Class": "rviz/MarkerArray", "Name": "Patrol graph", "Enabled": True, "Value": True,
         "Marker Topic": "/patrol_graph_markers", "Queue Size": 100, "Namespaces": {}},
        {"Class": "rviz/TF", "Name": "TF", "Enabled": False, "Value": False,
         "Show Arrows": False, "Show Axes": True, "Show Names": False, "Marker Scale": 0.5,
         "Update Interval": 0, "Frame Timeout": 15},
    ]
    displays += [robot_group(i, i < enabled) for i in range(robots)]
    return {
        "Panels": [
            {"Class": "rviz/Displays", "Name": "Displays", "Help Height": 70,
             "Property Tree Widget": {"Expanded": ["/Global Options1"], "Splitter Ratio": 0.6},
             "Tree Height": 500},
            {"Class": "rviz/Views", "Name": "Views", "Expanded": ["/Current View1"],
             "Splitter Ratio": 0.5},
            {"Class": "rviz/Time", "Name": "Time", "SyncMode": 0, "SyncSource": ""},
        ],
        "Preferences": {"PromptSaveOnExit": False},
        "Visualization Manager": {
            "Class": "",
            "Displays": displays,
            "Enabled": True,
            "Global Options": {"Background Color": "48; 48; 48", "Default Light": True,
                               "Fixed Frame": "map", "Frame Rate": 30},
            "Name": "root",
            "Tools": [
                {"Class": "rviz/Interact", "Hide Inactive Objects": True},
                {"Class": "rviz/MoveCamera"},
                {"Class": "rviz/Select"},
                {"Class": "rviz/FocusCamera"},
                {"Class": "rviz/Measure"},
                {"Class": "rviz/PublishPoint", "Single click": True, "Topic": "/clicked_point"},
            ],
            "Value": True,
            "Views": {"Current": view_for_extent(extent), "Saved": None},
        },
        "Window Geometry": {"Width": WINDOW[0], "Height": WINDOW[1], "X": 0, "Y": 0,
                            "QMainWindow State": DOCK_STATE,
                            "Hide Left Dock": False, "Hide Right Dock": True,
                            "Displays": {"collapsed": False}, "Views": {"collapsed": True},
                            "Time": {"collapsed": False}},
    }


def config_text(robots=8, enabled=4, extent=None, header=None):
    """The configuration as YAML text (the .rviz file), with an optional comment header."""
    body = yaml.safe_dump(make_config(robots, enabled, extent), sort_keys=False,
                          default_flow_style=False, width=1000)
    lines = "".join(f"# {h}\n" for h in (header or []))
    return lines + body


def map_extent(occupancy):
    """(xmin, xmax, ymin, ymax) in metres of an :class:`OccupancyMap`."""
    w, h = occupancy.size_m
    ox, oy = occupancy.origin[0], occupancy.origin[1]
    return (ox, ox + w, oy, oy + h)


def experiment_config_text(robots, map_name):
    """Configuration for one experiment: exactly ``robots`` groups, all enabled, view centred
    on ``map_name`` (a shipped map name or a yaml/.graph path). For the runner's
    ``rviz`` option, which can write it next to the run's results.

    Raises:
        PatrolInputError: unknown map or unreadable map files.
    """
    extent = map_extent(load_map(paths.map_files(map_name)[0]))
    return config_text(robots, robots, extent,
                       header=[f"rviz configuration for {robots} robot(s) on {map_name}"])
