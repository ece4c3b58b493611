"""Watching a running experiment from the runner's process: is the master up, the
simulator's status (sim time, pace), the monitor's GO / END and the visits, and the
progress figures read from the monitor's own files (docs/architecture.md, "runner")."""
import os
import time
import xmlrpc.client

from patrolling_sim.common.protocol import END, GO, MONITOR_ID, MSG_INIT, MSG_TARGET_REACHED
import json


def master_up(uri, timeout, stop=lambda: False):
    """True once the ROS master at ``uri`` answers (within ``timeout`` wall s, or until
    ``stop()`` is true)."""
    proxy = xmlrpc.client.ServerProxy(uri)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not stop():
        try:
            code, _, _ = proxy.getSystemState("/experiment_runner")
            if code == 1:
                return True
        except OSError:
            pass
        time.sleep(0.2)
    return False


def read_progress(prefix):
    """(complete cycles, average idleness or None) from the monitor's files."""
    cycles = 0
    try:
        with open(prefix + "_results.txt", encoding="utf-8") as f:
            for line in f:
                if line.startswith("Complete Patrol Cycles:"):
                    cycles = int(line.split("\t")[-1])
    except (OSError, ValueError):
        pass
    total = n = 0
    try:
        with open(prefix + "_idleness.csv", encoding="utf-8") as f:
            next(f, None)
            for line in f:
                parts = line.split(";")
                if len(parts) >= 4:
                    try:
                        total += float(parts[3])
                        n += 1
                    except ValueError:
                        pass
    except OSError:
        pass
    return cycles, (total / n if n else None)


def progress_line(watcher, prefix):
    """The runner's periodic progress line (figures as the monitor counts them)."""
    cycles, avg = read_progress(prefix)
    avg_s = f"{avg:.1f} s" if avg is not None else "-"
    rtf_s = f"{watcher.rtf:.2f}x" if watcher.rtf else "-"
    return (f"progress: sim {watcher.sim_time:.1f} s | go {'yes' if watcher.go else 'no'} | "
            f"cycles {cycles} | avg idleness {avg_s} | visits {watcher.visits} | "
            f"pace {rtf_s}")


class RosWatcher:
    """Follows the experiment from this process: the simulator's status (sim time and
    achieved real-time factor, every 2 s wall; cheaper than /clock at every step) and
    /results (GO, visits)."""

    def __init__(self, master_uri, status="/stage2d/status"):
        os.environ["ROS_MASTER_URI"] = master_uri
        os.environ["ROS_IP"] = "127.0.0.1"
        import rospy
        from std_msgs.msg import Int16MultiArray, String
        self.rospy = rospy
        self.sim_time = 0.0
        self.rtf = None
        self.status = {}            # the simulator's last status (JSON object)
        self.go = False
        self.sim_at_go = None
        self.end = False
        self.visits = 0
        self._reports = 0
        self._vertices = set()
        self.ready = set()
        rospy.init_node(f"experiment_runner_{os.getpid()}", anonymous=False,
                        disable_signals=True, disable_rosout=False)
        rospy.Subscriber(status, String, self._status, queue_size=1)
        rospy.Subscriber("/results", Int16MultiArray, self._results, queue_size=100)

    def _status(self, msg):
        try:
            st = json.loads(msg.data)
            self.sim_time = float(st["sim_time"])
            self.rtf = float(st["rtf"])
            self.status = st
        except (ValueError, KeyError, TypeError):
            pass

    def _results(self, msg):
        d = list(msg.data)
        if len(d) >= 3 and d[1] == MSG_INIT:
            if d[0] == MONITOR_ID and d[2] == GO:
                if not self.go:
                    self.sim_at_go = self.sim_time
                self.go = True
            elif d[0] == MONITOR_ID and d[2] == END:
                self.end = True
            elif d[0] >= 0:
                self.ready.add(d[0])
        elif len(d) >= 3 and d[1] == MSG_TARGET_REACHED and self.go:
            # counted as the monitor counts them: a vertex's first report (the start
            # vertex, usually) is not a visit (its counter starts at -1)
            self._reports += 1
            self._vertices.add(d[2])
            self.visits = self._reports - len(self._vertices)

    def close(self):
        try:
            self.rospy.signal_shutdown("experiment finished")
        except Exception:   # noqa: BLE001 - best effort at exit
            pass
