"""``scripts/graph_tool.py``: inspect, validate, draw and convert maps and patrol graphs.

Sub-commands::

    check [MAP ...]              parse maps (all shipped maps by default); print V/E, warnings
    info MAP                     one line per vertex: id, pixels, metres, neighbours
    startposes MAP N [--initpos FORM] [--seed S] [--alg ALG]   start positions for N robots
    draw MAP --out PNG           picture of the graph over the map
    write MAP --out GRAPH        write the graph back in .graph format
    msp MAP N                    check the shipped MSP route files for N robots
    init-map IMAGE --resolution R       write a map_server yaml for an image (png/pgm)
    extract MAP [--out GRAPH]    extract a patrol graph (and its picture) from a map
    coverage MAP [GRAPH]         share of the reachable free space the vertices see

MAP is a shipped map name or a path to a map's .yaml/.graph file.
"""
import sys

from patrolling_sim.common import paths
from patrolling_sim.model import map_bundle
from patrolling_sim.common.cli import CliParser, run_main, setup_logging
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.model.graph import (PatrolGraph, graph_warnings, load_graph, printed_edge_count,
                                        undirected_edge_count, write_graph)
import os
from patrolling_sim.extraction.coverage import check_graph
from patrolling_sim.extraction.coverage import coverage
from patrolling_sim.extraction.extract import DEFAULT_MARGIN
from patrolling_sim.extraction.extract import DEFAULT_MIN_DEAD_END
from patrolling_sim.extraction.extract import DEFAULT_SPACING
from patrolling_sim.extraction.extract import ExtractionParams
from patrolling_sim.extraction.extract import extract_graph
from patrolling_sim.extraction.extract import init_map_yaml
from patrolling_sim.model.draw import draw_graph
from patrolling_sim.model.draw import save_png
from patrolling_sim.planning.msp_routes import load_route
from patrolling_sim.startpos.initial_poses import ROBOT_RADIUS
from patrolling_sim.startpos.initial_poses import load_initial_poses
from patrolling_sim.startpos.resolve import start_positions
from spqrel_nav_lite.mapio import load_map


def _load(name):
    occ, G = map_bundle.load_map_bundle(name)
    return occ, G, PatrolGraph(G)


def cmd_check(args):
    names = args.maps or paths.available_maps()
    if not names:
        raise PatrolInputError(f"no maps found under {paths.maps_dir()}")
    for name in names:
        occ, G, pg = _load(name)
        warns = graph_warnings(G, occ)
        print(f"{paths.map_name(name)}: V={G.number_of_nodes()} E={undirected_edge_count(G)} "
              f"E*={printed_edge_count(G)} image={occ.width}x{occ.height} "
              f"res={occ.resolution} warnings={len(warns)}")
    return 0


def cmd_info(args):
    _, G, pg = _load(args.map)
    for v in range(pg.n):
        x, y = pg.pos[v]
        nb = " ".join(f"{w}:{c}" for w, c in pg.neighbors[v])
        print(f"{v}\t{int(pg.pos_px[v][0])}\t{int(pg.pos_px[v][1])}\t{x:.3f}\t{y:.3f}\t{nb}")
    return 0


def cmd_startposes(args):
    """Print the start position and vertex of each of ``args.n`` robots on ``args.map`` for
    ``args.initpos`` (any form, ``random`` drawn from ``args.seed``). Raises
    PatrolInputError when they cannot be placed."""
    if args.n < 1:
        raise PatrolInputError(f"argument N: team size must be >= 1, got {args.n}")
    occ, G, pg = _load(args.map)
    table = load_initial_poses(paths.initial_poses_file())
    map_dir = os.path.dirname(os.path.abspath(paths.map_files(args.map)[0]))
    pos, src = start_positions(paths.map_name(args.map), args.n, pg, occ, args.initpos, table,
                               paths.initial_poses_file(), alg=args.alg, seed=args.seed,
                               map_dir=map_dir)
    print(f"# {len(pos)} start positions ({src})")
    for k, (x, y) in enumerate(pos):
        print(f"robot_{k}\t{x:.3f}\t{y:.3f}\tvertex {pg.nearest_vertex(x, y)}")
    return 0


def cmd_draw(args):
    occ, G, pg = _load(args.map)
    save_png(draw_graph(occ, pg), args.out)
    print(args.out)
    return 0


def cmd_write(args):
    G = load_graph(paths.map_files(args.map)[1])
    write_graph(G, args.out)
    print(args.out)
    return 0


def cmd_msp(args):
    _, G, pg = _load(args.map)
    name = paths.map_name(args.map)
    bad = 0
    for i in range(args.n):
        f = paths.msp_route_file(name, args.n, i)
        try:
            r = load_route(f, pg)
            print(f"{f}: valid closed route of {len(r) - 1} steps")
        except PatrolInputError as e:
            bad += 1
            print(f"{e}")
    return 1 if bad else 0


def cmd_init_map(args):
    out = init_map_yaml(args.image, args.resolution, tuple(args.origin), args.out,
                        force=args.force, negate=args.negate)
    print(out)
    return 0


def _number(what):
    def conv(text):
        try:
            v = float(text)
        except ValueError:
            raise PatrolInputError(f"argument {what}: expected a number, got '{text}'") from None
        return v
    return conv


def cmd_extract(args):
    params = ExtractionParams(robot_radius=args.robot_radius, margin=args.margin,
                              spacing=args.spacing, min_dead_end=args.min_dead_end,
                              largest=args.largest).validate()
    yaml_path, graph_path = paths.map_files(args.map)
    out = args.out or graph_path
    png = args.png or os.path.splitext(out)[0] + "-graph.png"
    for f in (out, png):
        if os.path.exists(f) and not args.force:
            raise PatrolInputError(f"argument --out: {f} exists (use --force to overwrite, or "
                                   f"--out/--png to write elsewhere)")
    occ = load_map(yaml_path)
    res = extract_graph(occ, params, name=paths.map_name(out))
    G = res.graph
    problems = check_graph(occ, G, path_clearance=params.clearance)
    if problems:     # never expected: the extractor builds what the checker accepts
        raise PatrolInputError(f"{yaml_path}: extracted graph fails its check: {problems[0]}")
    pg = PatrolGraph(G)
    if res.dropped:
        shown = "; ".join(f"{a:.1f} m2 around ({x:.1f}, {y:.1f})" for a, x, y in res.dropped[:4])
        more = f" and {len(res.dropped) - 4} smaller" if len(res.dropped) > 4 else ""
        print(f"note: ignored {len(res.dropped)} separate piece(s) of usable free space "
              f"(outside the building, pockets under 10 % of the main piece, or --largest): "
              f"{shown}{more}")
    write_graph(G, out)
    tmp = f"{png}.tmp{os.getpid()}.png"
    save_png(draw_graph(occ, pg), tmp)
    os.replace(tmp, png)
    cov = coverage(occ, pg, args.sensing_radius)
    print(f"{out}: V={pg.n} E={undirected_edge_count(G)} spacing={params.spacing:g} m "
          f"coverage({args.sensing_radius:g} m)={100 * cov:.1f}% picture={png}")
    return 0


def cmd_coverage(args):
    if not args.radius > 0:
        raise PatrolInputError(f"argument --radius: must be > 0 metres, got {args.radius:g}")
    yaml_path, graph_path = paths.map_files(args.map)
    occ = load_map(yaml_path)
    G = load_graph(args.graph or graph_path, occupancy=occ)
    cov = coverage(occ, PatrolGraph(G), args.radius)
    print(f"{args.graph or graph_path}: V={G.number_of_nodes()} coverage({args.radius:g} m, "
          f"line of sight)={100 * cov:.1f}%")
    return 0


def main(argv):
    ap = CliParser(prog="graph_tool.py", description=__doc__.split("\n")[0])
    ap.add_argument("-v", "--verbose", action="store_true")
    sub = ap.add_subparsers(dest="cmd", required=True, parser_class=CliParser)
    p = sub.add_parser("check")
    p.add_argument("maps", nargs="*")
    p.set_defaults(fn=cmd_check)
    p = sub.add_parser("info")
    p.add_argument("map")
    p.set_defaults(fn=cmd_info)
    p = sub.add_parser("startposes")
    p.add_argument("map")
    p.add_argument("n", type=int)
    p.add_argument("--initpos", default="default",
                   help="'default', a table variant, 'optimised' (needs --alg), "
                        "'vertices:V0,V1,...', 'file:PATH' (or a bare path; relative to the "
                        "map's folder) or 'random' (drawn from --seed)")
    p.add_argument("--seed", type=int, default=0, help="the run's seed (--initpos random)")
    p.add_argument("--alg", help="algorithm the optimised start is chosen for")
    p.set_defaults(fn=cmd_startposes)
    p = sub.add_parser("draw")
    p.add_argument("map")
    p.add_argument("--out", required=True)
    p.set_defaults(fn=cmd_draw)
    p = sub.add_parser("write")
    p.add_argument("map")
    p.add_argument("--out", required=True)
    p.set_defaults(fn=cmd_write)
    p = sub.add_parser("msp")
    p.add_argument("map")
    p.add_argument("n", type=int)
    p.set_defaults(fn=cmd_msp)
    p = sub.add_parser("init-map", help="write a map_server yaml beside an image")
    p.add_argument("image")
    p.add_argument("--resolution", type=_number("--resolution"), required=True,
                   help="metres per pixel")
    p.add_argument("--origin", type=_number("--origin"), nargs=3, default=[0.0, 0.0, 0.0],
                   metavar=("X", "Y", "YAW"), help="pose of the lower-left pixel (0 0 0)")
    p.add_argument("--negate", action="store_true", help="white = occupied")
    p.add_argument("--out", help="yaml path (default: the image's name with .yaml)")
    p.add_argument("--force", action="store_true", help="overwrite an existing yaml")
    p.set_defaults(fn=cmd_init_map)
    p = sub.add_parser("extract", help="extract a patrol graph from a map")
    p.add_argument("map", help="map yaml (or shipped map name)")
    p.add_argument("--out", help="graph file (default: <map>.graph beside the yaml)")
    p.add_argument("--png", help="picture (default: <graph>-graph.png)")
    p.add_argument("--spacing", type=_number("--spacing"), default=DEFAULT_SPACING,
                   help=f"metres between vertices along corridors ({DEFAULT_SPACING:g})")
    p.add_argument("--min-dead-end", type=_number("--min-dead-end"),
                   default=DEFAULT_MIN_DEAD_END,
                   help=f"shortest dead-end branch kept, m ({DEFAULT_MIN_DEAD_END:g})")
    p.add_argument("--robot-radius", type=_number("--robot-radius"), default=ROBOT_RADIUS)
    p.add_argument("--margin", type=_number("--margin"), default=DEFAULT_MARGIN,
                   help=f"clearance on top of the robot radius, m ({DEFAULT_MARGIN:g})")
    p.add_argument("--largest", action="store_true",
                   help="free space in several pieces: extract the largest")
    p.add_argument("--sensing-radius", type=_number("--sensing-radius"), default=5.0)
    p.add_argument("--force", action="store_true", help="overwrite existing files")
    p.set_defaults(fn=cmd_extract)
    p = sub.add_parser("coverage", help="coverage of the free space by a graph")
    p.add_argument("map", help="map yaml (or shipped map name)")
    p.add_argument("graph", nargs="?", help="graph file (default: the map's)")
    p.add_argument("--radius", type=_number("--radius"), default=5.0,
                   help="sensing radius, m (5)")
    p.set_defaults(fn=cmd_coverage)
    args = ap.parse_args(argv)
    setup_logging(args.verbose)
    return args.fn(args)


def entry():
    sys.exit(run_main(main, "graph_tool.py"))
