"""The fidelity matrix: compact summaries of runs of the original's own agents on every
shipped map and team size (tests/unit/data/original_matrix/, README there), and the same
cells in this project's graph mode.

Shared by bench/original_agents.py (which appends the summary rows), bench/fidelity_matrix.py
(which writes docs/fidelity_matrix.md) and tests/unit/test_fidelity_matrix.py. The result
files are read with the package's own parsers (``report.loading.load_run`` for info.csv and
the idleness samples, ``monitor.metrics.read_visits`` for the visit log); nothing here
parses a monitor file itself.

A summary row (:data:`COLUMNS`) holds one run: who ran it (``agents``: ``original`` for the
original's agents, ``ours_separate`` / ``ours_shared`` for ours in ROS mode), the map, team
size, algorithm, run index, pace and duration asked for, the one-minute load average when it
started, what the monitor measured (average idleness = mean of the idleness samples, maximum
idleness, visits = idleness samples), the visit reports per vertex after GO (the first
visit of a vertex included, so 0 means never visited) and the robots whose agent process had
ended before the run did (``agents_exited``: space-separated ids, empty for none, ``-`` where
the run did not record it). A run with such a robot is the original's crash, not its
patrolling: :func:`cells` leaves it out (:func:`crashed` names such runs).
"""
import csv
import dataclasses
import os
import statistics

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "original_matrix")
RUNS = os.path.join(DATA, "runs.csv")
KNOWN = os.path.join(DATA, "known_differences.csv")
COLUMNS = ("agents", "map", "robots", "algorithm", "run", "speedup", "duration", "load1",
           "sim_duration", "real_duration", "termination", "start_vertices", "avg_idleness",
           "max_idleness", "visits", "visit_counts", "agents_exited")
#: relative tolerances of a cell's comparison with the mean of the original's runs
TOL = {"avg": 0.10, "max": 0.25, "visits": 0.10}
METRICS = ("avg", "max", "visits")
#: the agents' clock at GO in graph mode (s): in the runs of the original's agents the
#: clock starts with the world, GO came at 3.6-5.1 s and the agents' first goals at 7.6-10.8 s
#: (median 8.7 s; 9 runs read from their logs), after a start-up the graph world does not
#: have (the costmaps' clearing); 8 s puts graph mode's first decisions (GO + 0-1 s) at the
#: clock the original's agents decided at. Idleness-driven rules see it: a vertex an agent
#: has not visited counts from the clock's zero (docs/fidelity.md, "The clock at GO")
GO_TIME = 8.0
#: our graph mode's seeds for one cell (two: the DTA cells cost 1-4 s of CPU per run)
SEEDS = (0, 1)


def summary_row(results_dir, agents, alg, run, speedup, duration, load1, exited=None):
    """The summary row (dict keyed by :data:`COLUMNS`) of the one run under ``results_dir``,
    or None if it has no complete set of result files (no info.csv). ``exited``: the ids of
    the robots whose agent process ended before the run did (None: not recorded)."""
    import glob
    from patrolling_sim.model.graph import PatrolGraph
    from patrolling_sim.common import paths
    from patrolling_sim.monitor.metrics import read_visits
    from patrolling_sim.report.loading import load_run
    infos = glob.glob(os.path.join(str(results_dir), "**", "*_info.csv"), recursive=True)
    if len(infos) != 1:
        return None
    prefix = infos[0][:-len("_info.csv")]
    run_ = load_run(prefix)
    i = run_.info
    n = PatrolGraph.load(paths.map_files(i["map"])[1]).n
    counts = [0] * n
    if os.path.isfile(prefix + "_visits.csv"):
        for _, _, v in read_visits(prefix + "_visits.csv"):
            if 0 <= v < n:
                counts[v] += 1
    else:
        counts = None
    starts = _start_vertices(prefix)
    samples = run_.samples["Idleness"]
    return {"agents": agents, "map": i["map"], "robots": i["team_size"], "algorithm": alg,
            "run": run, "speedup": f"{speedup:g}", "duration": f"{duration:g}",
            "load1": f"{load1:.2f}", "sim_duration": f"{i['sim_duration']:g}",
            "real_duration": f"{i['real_duration']:g}", "termination": i["termination"],
            "start_vertices": " ".join(map(str, starts)) if starts else "",
            "avg_idleness": f"{float(samples.mean()):.3f}" if len(samples) else "",
            "max_idleness": f"{i['idl_max']:g}", "visits": i["total_visits"],
            "visit_counts": " ".join(map(str, counts)) if counts is not None else "",
            "agents_exited": "-" if exited is None else " ".join(map(str, exited))}


def _start_vertices(prefix):
    """The start vertices the runner resolved (``<prefix>_config.yaml``), [] if unknown."""
    import yaml
    path = prefix + "_config.yaml"
    if not os.path.isfile(path):
        return []
    with open(path, encoding="utf-8") as f:
        cfg = yaml.safe_load(f) or {}
    return [int(v) for v in cfg.get("start_vertices") or []]


def append_rows(path, rows):
    """Append ``rows`` (dicts keyed by :data:`COLUMNS`) to the CSV ``path`` (header first
    if the file is new or empty)."""
    new = not os.path.isfile(path) or os.path.getsize(path) == 0
    with open(path, "a", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        if new:
            w.writeheader()
        for r in rows:
            w.writerow(r)


def read_rows(path=RUNS):
    """The rows of a summary CSV, numbers converted (robots, run, visits int; figures
    float; ``visit_counts`` a list of int)."""
    out = []
    with open(path, newline="", encoding="utf-8") as f:
        for r in csv.DictReader(f):
            for k in ("robots", "run", "visits"):
                r[k] = int(r[k])
            for k in ("speedup", "duration", "load1", "sim_duration", "real_duration",
                      "avg_idleness", "max_idleness"):
                r[k] = float(r[k]) if r[k] != "" else None
            r["visit_counts"] = [int(c) for c in r["visit_counts"].split()]
            r["start_vertices"] = [int(c) for c in r["start_vertices"].split()]
            ex = (r.get("agents_exited") or "-").strip()
            r["agents_exited"] = None if ex == "-" else [int(c) for c in ex.split()]
            out.append(r)
    return out


def complete(row):
    """The run ended on its timeout after its whole duration (its figures are usable)."""
    return row["termination"] == "TIMEOUT" and row["sim_duration"] >= row["duration"]


def crashed(row):
    """Some robot's agent process ended before the run did (the row records it)."""
    return bool(row["agents_exited"])


def crashes(rows, agents="original"):
    """{(map, robots, algorithm, duration): number of complete runs left out because an
    agent process ended early}."""
    out = {}
    for r in rows:
        if r["agents"] == agents and complete(r) and crashed(r):
            key = (r["map"], r["robots"], r["algorithm"], r["duration"])
            out[key] = out.get(key, 0) + 1
    return out


def cells(rows, agents="original"):
    """{(map, robots, algorithm, duration): [(avg, max, visits)]} of the complete runs of
    ``agents`` in which no agent process ended early (:func:`crashed`), in the order first
    seen."""
    out = {}
    for r in rows:
        if r["agents"] == agents and complete(r) and not crashed(r):
            key = (r["map"], r["robots"], r["algorithm"], r["duration"])
            out.setdefault(key, []).append((r["avg_idleness"], r["max_idleness"], r["visits"]))
    return out


def mean_figures(runs):
    """(avg, max, visits) averaged over runs [(avg, max, visits)]."""
    return tuple(statistics.mean(r[k] for r in runs) for k in range(3))


def graph_config(map_name, robots, alg, seed, duration, go_time=None):
    """Graph mode in the abstract world's conditions: the shipped default start positions,
    straight-line travel at 1 m/s, no interference, no teammate positions heard (the world
    sends no move_base feedback), goal wait 0, no delay or loss, the agents' clock at GO
    :data:`GO_TIME` (or ``go_time``)."""
    from patrolling_sim.graphsim.config import GraphSimConfig
    kw = dict(map=map_name, robots=robots, alg=alg, seed=seed, duration=duration, speed=1.0,
              gwait=0.0, comm_delay=0.0, loss=0.0, initpos="default", travel="euclidean",
              interference=False, positions=False,
              go_time=GO_TIME if go_time is None else go_time)
    fields = {f.name for f in dataclasses.fields(GraphSimConfig)}
    return GraphSimConfig(**{k: v for k, v in kw.items() if k in fields})


def start_vertices(map_name, robots):
    """The start vertices of graph mode's default start positions for the map and team."""
    from patrolling_sim.graphsim.simulator import GraphSimulator
    return list(GraphSimulator(graph_config(map_name, robots, "CR", 0, 1.0)).start_vertices)


def fully_known(known, map_name, robots, alg):
    """Every metric of the cell is a documented difference (nothing left to compare)."""
    return all(known_reason(known, map_name, robots, alg, m) for m in METRICS)


def graph_run(map_name, robots, alg, seed, duration):
    """(avg, max, visits, start vertices) of one graph-mode run."""
    from patrolling_sim.graphsim.simulator import GraphSimulator
    sim = GraphSimulator(graph_config(map_name, robots, alg, seed, duration))
    s = sim.run(write=False)
    return s.global_avg, s.global_max, s.total_visits, list(sim.start_vertices)


def compare(ref, got):
    """{metric: (relative difference of ``got`` from ``ref``, within tolerance)} for the
    means ``ref`` and ``got`` (avg, max, visits)."""
    out = {}
    for k, m in enumerate(METRICS):
        rel = (got[k] - ref[k]) / ref[k] if ref[k] else float("inf")
        out[m] = (rel, abs(rel) <= TOL[m])
    return out


def known_differences(path=KNOWN):
    """{(map, robots, algorithm, metric): reason} of the documented known differences
    (``robots`` and ``metric`` may be ``*``: any); {} if ``path`` does not exist.

    Raises:
        ValueError: a row without exactly the five fields (e.g. a reason holding a quote
            that is not doubled, which splits it), naming the file and line.
    """
    if not os.path.isfile(path):
        return {}
    out = {}
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        for r in reader:
            if None in r or None in r.values():
                # a quote inside a reason that is not doubled splits the reason
                raise ValueError(f"{path}:{reader.line_num}: expected the 5 fields "
                                 f"map,robots,algorithm,metric,reason")
            out[(r["map"], r["robots"], r["algorithm"], r["metric"])] = r["reason"]
    return out


def known_reason(known, map_name, robots, alg, metric):
    """The documented reason why ``metric`` of the cell differs, or None."""
    for key in ((map_name, str(robots), alg, metric), (map_name, "*", alg, metric),
                (map_name, str(robots), alg, "*"), (map_name, "*", alg, "*"),
                ("*", "*", alg, metric), ("*", "*", alg, "*")):
        if key in known:
            return known[key]
    return None
