"""Helpers shared by the agent/monitor rostest checkers (not a test by itself)."""
import glob
import os
import re
import threading
import time

import rospy
from std_msgs.msg import Int16MultiArray

GO = [-1, 10, 100]
END = [-1, 10, 999]

IDLENESS_HEADER = "Time;Robot;Node;Idleness;Interferences"
TIMERESULTS_HEADER = "Time;Idleness min;Idleness avg;Idleness stddev;Idleness max;Interferences"
IDLENESS_ROW = re.compile(r"^-?\d+\.\d;\d+;\d+;\d+\.\d;\d+$")
# fields 15-18 (idleness min/avg/SD/max) are empty when the run has no idleness sample
# (docs/monitor.md): a run with a single visit per vertex measured no idleness
INFO_FORMATS = [r"[^;]+", r"\d+", r"[^;]*", r"\d+\.\d", r"\d+\.\d\d", r"[^;]*", r"[^;]+",
                r"[^;]*", r"[^;]+", r"\d{8}_\d{6}", r"\d+\.\d", r"\d+\.\d", r"\d+",
                r"[A-Z]+", r"(\d+\.\d)?", r"(\d+\.\d)?", r"(\d+\.\d)?", r"(\d+\.\d)?",
                r"\d+\.\d\d", r"\d+", r"\d+\.\d", r"\d+"]


class ResultsRecorder:
    """Records every /results message with its arrival time (ROS time)."""

    def __init__(self):
        self.lock = threading.Lock()
        self.msgs = []                 # (t, data)
        self.pub = rospy.Publisher("/results", Int16MultiArray, queue_size=100)
        self.sub = rospy.Subscriber("/results", Int16MultiArray, self._cb, queue_size=1000)

    def _cb(self, msg):
        with self.lock:
            self.msgs.append((rospy.get_time(), list(msg.data)))

    def snapshot(self):
        with self.lock:
            return list(self.msgs)

    def of_type(self, kind, sender=None):
        return [(t, d) for t, d in self.snapshot()
                if len(d) > 1 and d[1] == kind and (sender is None or d[0] == sender)]

    def first(self, data):
        for t, d in self.snapshot():
            if d == data:
                return t
        return None

    def wait_for(self, pred, timeout, what):
        """Wait (wall time) until ``pred()`` is true; AssertionError naming ``what``."""
        end = time.time() + timeout
        while time.time() < end and not rospy.is_shutdown():
            if pred():
                return
            time.sleep(0.1)
        if not pred():
            raise AssertionError(f"timeout after {timeout} s waiting for {what}")

    def send(self, data):
        self.pub.publish(Int16MultiArray(data=list(data)))

    def connected_to_publishers(self, at_least):
        """True when this recorder's subscriber is connected to every other publisher of
        /results the master knows, and they are at least ``at_least`` nodes: only from then
        on can no message be missed. Raises rosgraph.MasterException if a node is gone."""
        import rosgraph
        me = rospy.get_name()
        master = rosgraph.Master(me)
        pubs = next((names for topic, names in master.getSystemState()[0]
                     if topic == "/results"), [])
        pubs = [name for name in pubs if name != me]
        have = {c.endpoint_id for c in self.sub.impl.connections}
        return len(pubs) >= at_least and {master.lookupNode(name) for name in pubs} <= have


def find_result_files(results_dir, timeout=10.0, need_info=True):
    """Prefix of the single run under ``results_dir`` (waits for info.csv if asked)."""
    end = time.time() + timeout
    while True:
        infos = glob.glob(os.path.join(results_dir, "**", "*_info.csv"), recursive=True)
        idls = glob.glob(os.path.join(results_dir, "**", "*_idleness.csv"), recursive=True)
        if (infos if need_info else idls) or time.time() > end:
            break
        time.sleep(0.2)
    files = infos if need_info else idls
    if len(files) != 1:
        raise AssertionError(f"expected one run under {results_dir}, found {files}")
    return files[0][: -len("_info.csv" if need_info else "_idleness.csv")]


def read(path):
    with open(path, encoding="utf-8") as f:
        return f.read()


def check_info_line(tc, text):
    """22 fields in the original's formats; returns the fields."""
    tc.assertTrue(text.endswith("\n") and text.count("\n") == 1, repr(text))
    fields = text.rstrip("\n").split(";")
    tc.assertEqual(len(fields), 22, fields)
    for k, (f, pat) in enumerate(zip(fields, INFO_FORMATS)):
        tc.assertRegex(f, "^" + pat + "$", f"info.csv field {k + 1}: {f!r}")
    return fields


def check_idleness_file(tc, text):
    lines = text.splitlines()
    tc.assertEqual(lines[0], IDLENESS_HEADER)
    for ln in lines[1:]:
        tc.assertRegex(ln, IDLENESS_ROW)
    return [ln.split(";") for ln in lines[1:]]


def node_pid(node_name):
    """Process id of a node through its XML-RPC API."""
    import rosgraph
    from xmlrpc.client import ServerProxy
    try:
        uri = rosgraph.Master(rospy.get_name()).lookupNode(node_name)
    except rosgraph.MasterError:
        raise AssertionError(f"node {node_name} is not registered") from None
    code, _msg, pid = ServerProxy(uri).getPid(rospy.get_name())
    if code != 1:
        raise AssertionError(f"getPid of {node_name} failed")
    return pid


def reference_dir():
    from patrolling_sim.common import paths
    return os.path.join(paths.data_root(), "tests", "unit", "data", "original_output_example")


_NUM = re.compile(r"-?\d+(?:\.(\d+))?")


def shape(line):
    """A line with every number replaced by its kind (I, F1, F2...), for format checks."""
    return _NUM.sub(lambda m: "F%d" % len(m.group(1)) if m.group(1) else "I", line)


def first_block(text):
    """Lines of the first results.txt block (up to and including the dashes line)."""
    lines = text.split("\n")
    end = next(k for k, ln in enumerate(lines) if ln.startswith("-" * 20))
    return lines[: end + 3]
