"""A run's scenario: its communication model and robot failures, checked before the run and
recorded after it in ``<prefix>_scenario.yaml`` by both modes (``docs/scenarios.md``)::

    comm, schedule = check_scenario("bernoulli:p=0.3", "2@600", team_size=6, duration=3600)
    ... run ...
    write_scenario(prefix, "bernoulli:p=0.3", "2@600", schedule, monitor.failures,
                   {rid: core.comm_counters() for ...}, seed=seed, mode="graph")
    scenario_columns(prefix)     # tidy columns for a campaign table, failure impact included

The file (YAML)::

    comm: bernoulli:p=0.3            # the model as parsed back (describe())
    attrition: 2@600                 # the option as given
    schedule: 2@600                  # the explicit schedule it gave for this seed
    seed: 0
    mode: graph
    failures: [{robot: 2, t_fail: 600.0, t_repair: null}]   # what the monitor recorded
    counters: {total: {sent: .., delivered: .., lost: ..}, robots: {0: {...}, ...}}
"""
import math
import os
from typing import Dict, List, Optional, Sequence, Tuple

from patrolling_sim.scenarios.attrition import Failure, describe, parse_attrition
from patrolling_sim.scenarios.comm import CommModel, parse_comm
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.common.textfile import write_atomic
import yaml
from patrolling_sim.model import map_bundle
from patrolling_sim.monitor.metrics import failure_impact
from patrolling_sim.monitor.metrics import graph_idleness_series
from patrolling_sim.monitor.metrics import read_visits
from patrolling_sim.monitor.results import parse_info_line

SUFFIX = "_scenario.yaml"


def is_perfect(comm: Optional[str]) -> bool:
    """True for the perfect model spellings (no model applied at all)."""
    return (comm or "perfect").strip().lower() in ("", "perfect", "none")


def check_scenario(comm: Optional[str], attrition: Optional[str], team_size: int,
                   duration: float = math.inf, seed: int = 0, occupancy=None,
                   what_comm: str = "--comm", what_attr: str = "--attrition"
                   ) -> Tuple[CommModel, List[Failure]]:
    """The parsed model (seeded ``seed``) and the failure schedule of a run.

    Raises:
        PatrolInputError: one line naming the option and what is wrong (also for a failure
            after the end of the run, which would never happen).
    """
    model = parse_comm(comm or "perfect", seed=seed, occupancy=occupancy, what=what_comm)
    schedule = parse_attrition(attrition, team_size, duration if duration and duration > 0
                               else math.inf, seed=seed, what=what_attr)
    for f in schedule:
        if duration and duration > 0 and f.t >= duration:
            raise PatrolInputError(f"{what_attr}: robot {f.robot} fails at {f.t:g} s, not "
                                   f"before the end of the run ({duration:g} s)")
    return model, schedule


def total_counters(counters: Dict[int, Dict[str, int]]) -> Dict[str, int]:
    """Sum of the robots' receiver counters."""
    out: Dict[str, int] = {}
    for c in counters.values():
        for k, v in c.items():
            out[k] = out.get(k, 0) + int(v)
    return out


def write_scenario(prefix: str, comm_spec: Optional[str], attrition_spec: Optional[str],
                   schedule: Sequence[Failure], failures: Sequence[Sequence],
                   counters: Dict[int, Dict[str, int]], seed: int = 0, mode: str = "graph",
                   occupancy=None) -> str:
    """Write ``<prefix>_scenario.yaml`` (module docstring) atomically; returns its path.
    ``failures``: the monitor's ``[robot, t_fail, t_repair|None]`` records."""
    model = parse_comm(comm_spec or "perfect", occupancy=occupancy)
    doc = {
        "comm": model.describe(),
        "attrition": (attrition_spec or "none").strip() or "none",
        "schedule": describe(list(schedule)),
        "seed": int(seed),
        "mode": mode,
        "failures": [{"robot": int(f[0]), "t_fail": round(float(f[1]), 3),
                      "t_repair": None if f[2] is None else round(float(f[2]), 3)}
                     for f in failures],
        "counters": {"total": total_counters(counters),
                     "robots": {int(k): {kk: int(vv) for kk, vv in v.items()}
                                for k, v in sorted(counters.items())}},
    }
    return write_atomic(prefix + SUFFIX, yaml.safe_dump(doc, sort_keys=False))


def read_scenario(prefix: str) -> Optional[dict]:
    """The scenario record of a run, or None if it has none.

    Raises:
        ValueError: a malformed file (one line naming it)."""
    path = prefix + SUFFIX
    if not os.path.exists(path):
        return None
    try:
        with open(path, encoding="utf-8") as f:
            doc = yaml.safe_load(f)
    except yaml.YAMLError as e:
        raise ValueError(f"{path}: not valid YAML ({str(e).splitlines()[0]})")
    if not isinstance(doc, dict) or "comm" not in doc or "failures" not in doc:
        raise ValueError(f"{path}: expected a mapping with 'comm' and 'failures'")
    return doc


def failure_impacts(prefix: str, doc: dict, n_vertices: int, duration: float):
    """:class:`~patrolling_sim.monitor.metrics.FailureImpact` of every recorded failure of the run
    (graph idleness from ``<prefix>_visits.csv``; each failure's window ends at the next
    failure or at the end of the run), one per distinct failure time."""
    # failures at the same instant (e.g. two robots at 1200 s) are one event
    fails = sorted({float(f["t_fail"]) for f in doc.get("failures") or []})
    if not fails or not os.path.exists(prefix + "_visits.csv"):
        return []
    times, series = graph_idleness_series(read_visits(prefix + "_visits.csv"), n_vertices,
                                          duration)
    ends = fails[1:] + [duration]
    return [failure_impact(times, series, t, e) for t, e in zip(fails, ends)]


def scenario_columns(prefix: str, n_vertices: Optional[int] = None,
                     duration: Optional[float] = None) -> Dict[str, object]:
    """Tidy columns of a run's scenario for a campaign table ({} if the run has no scenario
    file): comm, attrition, failures, msgs_sent/delivered/lost, delivered_share, and for the
    first failure idl_before, idl_after, settle_time (s). ``n_vertices``/``duration`` default
    to the run's info file."""
    doc = read_scenario(prefix)
    if doc is None:
        return {}
    tot = (doc.get("counters") or {}).get("total") or {}
    sent = int(tot.get("sent", 0))
    out = {"comm": doc["comm"], "attrition": doc.get("schedule", "none"),
           "failures": len(doc["failures"]),
           "first_failure": doc["failures"][0]["t_fail"] if doc["failures"] else None,
           "msgs_sent": sent, "msgs_delivered": int(tot.get("delivered", 0)),
           "msgs_lost": int(tot.get("lost", 0)),
           "delivered_share": round(tot.get("delivered", 0) / sent, 4) if sent else None,
           "idl_before": None, "idl_after": None, "settle_time": None}
    if doc["failures"]:
        if n_vertices is None or duration is None:
            with open(prefix + "_info.csv", encoding="utf-8") as f:
                info = parse_info_line(f.read().strip().splitlines()[-1],
                                       prefix + "_info.csv")
            n_vertices = n_vertices or _vertices(info)
            duration = duration or float(info["sim_duration"])
        imp = failure_impacts(prefix, doc, n_vertices, duration)
        if imp:
            r = lambda x: None if x is None or not math.isfinite(x) else round(x, 2)
            out.update(idl_before=r(imp[0].before), idl_after=r(imp[0].after),
                       settle_time=r(imp[0].settle_time))
    return out


def _vertices(info: dict) -> int:
    return map_bundle.vertex_count(info["map"])


def scenario_metrics(prefix: str, n_vertices: int, duration: float) -> Dict[str, object]:
    """The scenario part of a run's metrics file (``extra: {scenario: ...}``): the model, the
    message counters, and the impact of **each** failure time (before, after, settle time,
    and the robots that failed then); {} if the run has no scenario file."""
    doc = read_scenario(prefix)
    if doc is None:
        return {}
    r = lambda x: None if x is None or not math.isfinite(x) else round(float(x), 2)
    impacts = []
    for imp in failure_impacts(prefix, doc, n_vertices, duration):
        robots = sorted(int(f["robot"]) for f in doc["failures"]
                        if float(f["t_fail"]) == imp.t_fail)
        impacts.append({"t_fail": imp.t_fail, "robots": robots, "before": r(imp.before),
                        "after": r(imp.after), "settle_time": r(imp.settle_time)})
    return {"comm": doc["comm"], "schedule": doc.get("schedule", "none"),
            "messages": (doc.get("counters") or {}).get("total", {}),
            "failures": impacts}
