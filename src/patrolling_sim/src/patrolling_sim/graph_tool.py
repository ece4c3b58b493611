"""``scripts/graph_tool.py``: inspect, validate, draw and convert maps and patrol graphs.

Sub-commands::

    check [MAP ...]              parse maps (all shipped maps by default); print V/E, warnings
    info MAP                     one line per vertex: id, pixels, metres, neighbours
    startposes MAP N [--initpos VARIANT]   start positions for N robots
    draw MAP --out PNG           picture of the graph over the map
    write MAP --out GRAPH        write the graph back in .graph format
    msp MAP N                    check the shipped MSP route files for N robots

MAP is a shipped map name or a path to a map's .yaml/.graph file.
"""
import sys

from . import paths
from .cli import CliParser, run_main, setup_logging
from .errors import PatrolInputError
from .graph import (PatrolGraph, graph_warnings, load_graph, printed_edge_count,
                    undirected_edge_count, write_graph)


def _load(name):
    occ, G = paths.load_map_bundle(name)
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
    from .initial_poses import load_initial_poses, start_positions
    if args.n < 1:
        raise PatrolInputError(f"argument N: team size must be >= 1, got {args.n}")
    occ, G, pg = _load(args.map)
    table = load_initial_poses(paths.initial_poses_file())
    pos, src = start_positions(paths.map_name(args.map), args.n, pg, occ, args.initpos, table,
                               paths.initial_poses_file())
    print(f"# {len(pos)} start positions ({src})")
    for k, (x, y) in enumerate(pos):
        print(f"robot_{k}\t{x:.3f}\t{y:.3f}\tvertex {pg.nearest_vertex(x, y)}")
    return 0


def cmd_draw(args):
    from .draw import draw_graph, save_png
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
    from .msp_routes import load_route
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
    p.add_argument("--initpos", default="default")
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
    args = ap.parse_args(argv)
    setup_logging(args.verbose)
    return args.fn(args)


def entry():
    sys.exit(run_main(main, "graph_tool.py"))
