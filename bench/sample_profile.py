#!/usr/bin/python3
"""Sampling profiler for the navigation processes of a full experiment (py-spy is not in
Debian): where do nav_host / robot_nav spend their CPU?

It runs ``scripts/start_experiments.py`` with the given arguments and a ``sitecustomize``
module on PYTHONPATH that, in every Python process whose command line matches ``--match``
(default: nav_host and robot_nav), starts a daemon thread sampling ``sys._current_frames()``
every ``--interval`` s. A sample of a thread that is waiting (its innermost frame in a
wait/select/poll/sleep/recv function) counts as idle; the others are attributed to

- the innermost frame ("self" time per function), and
- a category, from the innermost frame of our navigation code found in the stack (laser and
  obstacle memory, localiser update, planning, controller, publishing, ROS message handling).

Every process writes its counts (JSON) to the output folder every 10 s and at exit; the
summary adds them up and prints the shares of the busy samples.

With ``--cprofile`` it runs a deterministic profiler instead: ``cProfile`` in every thread of
the matching processes, timed by the thread's own CPU clock (``time.thread_time``), dumped
(``nav_<pid>.prof``, pstats format) when the node shuts down; the summary lists the
navigation's functions and rospy's message code by cumulative time. It slows Python code
down (a 12-robot run reaches about half its pace), more so code that makes many small calls,
such as building ROS messages, so read its shares as upper bounds for such code.

Usage:
    bench/sample_profile.py [--out DIR] [--interval 0.005] [--match nav_host robot_nav]
        [--cprofile] --
        --map grid --robots 12 --alg CGG --loc fake_localization --timeout 300 --speedup 20
        --processes pooled
"""
import argparse
import glob
import json
import os
import subprocess
import sys
import tempfile
from collections import Counter

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
#: innermost Python frames of a thread blocked in C (socket reads, sleeps, lock waits)
IDLE = ("wait", "select", "poll", "sleep", "accept", "recv", "recv_into", "read", "readline",
        "_recv", "spin", "acquire", "join", "epoll", "get", "recv_buff", "wallsleep",
        "readinto", "_handle_request", "handle_request", "serve_forever", "run")
#: category of the innermost navigation frame: (file suffix, function or "*") -> category
CATEGORIES = [
    ("particle_filter.py", "update", "localiser: likelihood"),
    ("particle_filter.py", "*", "localiser: motion/resample"),
    ("amcl_node.py", "*", "localiser: other"),
    ("fake_localization_node.py", "*", "localiser: fake"),
    ("obstacles.py", "*", "laser: obstacle memory"),
    ("move_base_node.py", "laser", "laser: points + field"),
    ("planner.py", "*", "planning"),
    ("planner_grid.py", "*", "planning"),
    ("obstacle_search.py", "*", "planning"),
    ("controller.py", "*", "controller"),
    ("move_base_node.py", "send", "publishing cmd_vel"),
    ("move_base_node.py", "publish_plan", "publishing plan"),
    ("move_base_goal.py", "*", "control loop (other)"),
    ("control_loop.py", "*", "control loop (other)"),
    ("goal_waits.py", "*", "control loop (other)"),
    ("move_base_node.py", "*", "move_base inputs"),
    ("geometry.py", "*", "geometry"),
]

SITE = '''
import os, sys, threading, time, json, atexit
from collections import Counter
_match = os.environ.get("NAV_PROFILE_MATCH", "").split()
_argv = " ".join(sys.argv)
if _match and any(m in _argv for m in _match) and "sample_profile" not in _argv:
    _out = os.path.join(os.environ["NAV_PROFILE_OUT"], "prof_%d.json" % os.getpid())
    _dt = float(os.environ.get("NAV_PROFILE_INTERVAL", "0.005"))
    _stacks = Counter()
    _lock = threading.Lock()

    def _dump():
        with _lock:
            data = {"argv": sys.argv, "stacks": [[list(k), v] for k, v in _stacks.items()]}
        tmp = _out + ".tmp"
        with open(tmp, "w") as f:
            json.dump(data, f)
        os.replace(tmp, _out)

    def _run():
        me = threading.get_ident()
        last = time.monotonic()
        while True:
            time.sleep(_dt)
            frames = sys._current_frames()
            with _lock:
                for tid, fr in frames.items():
                    if tid == me:
                        continue
                    stack = []
                    while fr is not None and len(stack) < 40:
                        c = fr.f_code
                        stack.append(os.path.basename(c.co_filename) + ":" + c.co_name)
                        fr = fr.f_back
                    _stacks[tuple(stack)] += 1
            if time.monotonic() - last > 10:
                last = time.monotonic()
                _dump()

    threading.Thread(target=_run, daemon=True, name="sample_profile").start()
    atexit.register(_dump)
'''

CPROFILE_SITE = '''
import os, sys
_match = os.environ.get("NAV_PROFILE_MATCH", "").split()
_argv = " ".join(sys.argv)
if _match and any(m in _argv for m in _match) and "sample_profile" not in _argv:
    import cProfile, pstats, threading, time
    _profs, _lock = [], threading.Lock()

    def _start_thread(*_):
        sys.setprofile(None)
        p = cProfile.Profile(time.thread_time)
        with _lock:
            _profs.append(p)
        p.enable()

    threading.setprofile(_start_thread)        # every thread started from now on
    _start_thread()                            # and this one

    def _dump():
        with _lock:
            profs = list(_profs)
        stats = None
        for p in profs:
            try:
                s = pstats.Stats(p)
            except TypeError:                  # a thread that recorded nothing
                continue
            stats = s if stats is None else stats.add(s)
        if stats is not None:
            stats.dump_stats(os.path.join(os.environ["NAV_PROFILE_OUT"],
                                          "nav_%d.prof" % os.getpid()))
    import rospy
    rospy.on_shutdown(_dump)
'''


def summarise_cprofile(out_dir, top=30):
    import io
    import pstats
    files = sorted(glob.glob(os.path.join(out_dir, "nav_*.prof")))
    if not files:
        return f"no profiles in {out_dir}"
    buf = io.StringIO()
    stats = pstats.Stats(*files, stream=buf)
    stats.sort_stats("cumulative").print_stats(r"spqrel_nav_lite|rospy/(topics|msg)|actionlib",
                                               top)
    return f"{len(files)} process(es)\n" + buf.getvalue()


#: helpers shared by several callers: the caller decides the category
PASS_THROUGH = {"particle_filter.py:lookup", "particle_filter.py:is_free"}


def category(stack):
    for frame in stack:                        # innermost first
        if frame in PASS_THROUGH:
            continue
        fname, func = frame.split(":", 1)
        for suffix, f, cat in CATEGORIES:
            if fname == suffix and f in ("*", func):
                return cat
    return "ROS messaging / other"


def summarise(out_dir, top=25):
    busy, idle = Counter(), 0
    selfs = Counter()
    files = glob.glob(os.path.join(out_dir, "prof_*.json"))
    for path in files:
        with open(path) as f:
            data = json.load(f)
        for stack, n in data["stacks"]:
            leaf = stack[0].split(":", 1)[1] if stack else ""
            if leaf in IDLE or leaf.startswith("_wait"):
                idle += n
                continue
            busy[category(stack)] += n
            selfs[stack[0]] += n
    total = sum(busy.values())
    lines = [f"{len(files)} process(es), {total} busy samples, {idle} idle samples"]
    lines.append("\n| category | share of busy samples |\n|---|---|")
    for cat, n in busy.most_common():
        lines.append(f"| {cat} | {100.0 * n / max(1, total):.1f} % |")
    lines.append("\n| innermost function (self) | share |\n|---|---|")
    for fn, n in selfs.most_common(top):
        lines.append(f"| {fn} | {100.0 * n / max(1, total):.1f} % |")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", help="folder for the per-process counts (default: a temporary "
                    "one)")
    ap.add_argument("--interval", type=float, default=0.005)
    ap.add_argument("--match", nargs="+", default=["nav_host", "robot_nav"])
    ap.add_argument("--cprofile", action="store_true",
                    help="cProfile every thread (CPU time) instead of sampling stacks")
    ap.add_argument("--summary-only", action="store_true",
                    help="only summarise the counts already in --out")
    ap.add_argument("args", nargs=argparse.REMAINDER,
                    help="-- then the arguments of scripts/start_experiments.py")
    a = ap.parse_args()
    out = a.out or tempfile.mkdtemp(prefix="nav_profile_")
    os.makedirs(out, exist_ok=True)
    if not a.summary_only:
        site = tempfile.mkdtemp(prefix="nav_profile_site_")
        with open(os.path.join(site, "sitecustomize.py"), "w") as f:
            f.write(CPROFILE_SITE if a.cprofile else SITE)
        env = dict(os.environ)
        env["PYTHONPATH"] = site + (":" + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        env.update(NAV_PROFILE_OUT=os.path.abspath(out), NAV_PROFILE_MATCH=" ".join(a.match),
                   NAV_PROFILE_INTERVAL=str(a.interval))
        args = a.args[1:] if a.args[:1] == ["--"] else a.args
        cmd = [sys.executable, os.path.join(ROOT, "scripts", "start_experiments.py"),
               "--headless"] + args
        rc = subprocess.call(cmd, env=env)
        if rc != 0:
            print(f"sample_profile: the experiment exited with {rc}", file=sys.stderr)
    print(summarise_cprofile(out) if a.cprofile else summarise(out))


if __name__ == "__main__":
    main()
