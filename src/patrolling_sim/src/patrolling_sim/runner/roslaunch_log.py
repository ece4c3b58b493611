"""Reading roslaunch's own output: which node died, with which exit code, and its log.

roslaunch names each process that ends in its output (``<prefix>_logs/roslaunch.log``):
``[robot_0/robot_nav-5] process has died [pid .., exit code ..``, ``REQUIRED process
[stage2d-2] has died!`` (the exit code and log file on the following lines) and
``cannot launch node of type [...]``. :class:`RoslaunchLog` follows that file and turns
those lines into death records; :func:`describe_node` names a process for a person
(docs/architecture.md, "runner").
"""
import re

_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def _strip_ansi(line):
    return _ANSI.sub("", line)


def describe_node(node):
    """(description, robot id or None) of a roslaunch process name such as
    ``robot_0/robot_nav-5``, ``stage2d-2``, ``patrol_robot1-9``, ``master``."""
    name = re.sub(r"-\d+$", "", node.strip("/"))
    m = re.match(r"robot_(\d+)/(.+)$", name)
    if m:
        rid = int(m.group(1))
        return f"robot {rid}'s navigation ({name})", rid
    m = re.match(r"patrol_robot(\d+)$", name)
    if m:
        rid = int(m.group(1))
        return f"robot {rid}'s agent ({name})", rid
    known = {"master": "the ROS master (rosmaster)", "stage2d": "the simulator (stage2d)",
             "monitor": "the monitor", "map_server": "the map server (map_server)",
             "patrol_agents": "the agents (patrol_agents)", "rviz": "rviz"}
    return known.get(name, f"node {name}"), None


def is_monitor(death):
    """True if a death record is the monitor's."""
    return describe_node(death["node"])[0] == "the monitor"


class RoslaunchLog:
    """Follows roslaunch's output file and collects the deaths it reports:
    dicts ``{node, exit_code, log, required, launch_error}`` in order."""

    def __init__(self, path):
        self.path = path
        self.pos = 0
        self.partial = ""
        self.deaths = []
        self._pending = None        # REQUIRED process [x] has died! -> next line has the code

    def poll(self):
        """The deaths reported since the last call (also appended to :attr:`deaths`)."""
        try:
            with open(self.path, encoding="utf-8", errors="replace") as f:
                f.seek(self.pos)
                data = f.read()
                self.pos = f.tell()
        except OSError:
            return []
        if not data:
            return []
        text = self.partial + data
        lines = text.split("\n")
        self.partial = lines.pop()
        new = []
        for line in lines:
            d = self._line(_strip_ansi(line).strip())
            if d is not None:
                self.deaths.append(d)
                new.append(d)
        return new

    def _line(self, line):
        m = re.search(r"REQUIRED process \[([^\]]+)\] has died!", line)
        if m:
            self._pending = {"node": m.group(1), "exit_code": None, "log": None,
                             "required": True, "launch_error": False}
            return None
        if self._pending is not None:
            return self._required_detail(line)
        m = re.match(r"\[([^\]]+)\] process has (died|finished cleanly)(.*)$", line)
        if m:
            code = re.search(r"exit code (-?\d+)", m.group(3))
            return {"node": m.group(1), "exit_code": int(code.group(1)) if code else
                    (0 if m.group(2) == "finished cleanly" else None), "log": None,
                    "required": False, "launch_error": False}
        if line.startswith("log file:") and self.deaths:
            self.deaths[-1]["log"] = line[len("log file:"):].strip()
            return None
        m = re.search(r"cannot launch node of type \[([^\]]+)\]", line)
        if m:
            return {"node": m.group(1), "exit_code": None, "log": None, "required": False,
                    "launch_error": True, "message": line}
        return None

    def _required_detail(self, line):
        """A line after ``REQUIRED process [x] has died!``: its exit code and log file, or
        the end of that report (the pending death is returned)."""
        d = self._pending
        m = re.search(r"exit code (-?\d+)", line)
        if m:
            d["exit_code"] = int(m.group(1))
            return None
        if "finished cleanly" in line:
            d["exit_code"] = 0
            return None
        if line.startswith("log file:"):
            d["log"] = line[len("log file:"):].strip()
            return None
        if "without exit code" in line:
            return None
        self._pending = None
        return d
