"""Tk launcher, like the original's "MRP Experiment Launcher".

The window edits an :class:`ExperimentConfig` (map, team size, algorithm, localisation,
navigation, goal wait, communication delay, speed-up, timeout, communication model,
failures, and the policy file an algorithm such as POLICY reads: ``--policy``, typed or
chosen with the "..." button, kept as an absolute path), remembers the last one in
``$PATROLLING_SIM_GUI_CONFIG`` (default ``~/.config/patrolling_sim/last_config.yaml``, the
same YAML format as ``--config``), and runs the experiment as a headless child process
(``start_experiments.py --headless --config FILE``) whose progress lines it shows live:
sim time, patrol cycles, average idleness. Stop sends SIGINT to that child, which stops
the run in order so the result files are complete.
"""
import os
import queue
import re
import signal
import subprocess
import sys
import tempfile
import threading

from patrolling_sim.common import paths
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.runner.config import LOC_MODES, NAV_MODES, ExperimentConfig, load_config_file
from patrolling_sim.algorithms import REGISTRY

POLL_MS = 100
PROGRESS_RE = re.compile(r"progress: sim ([\d.]+) s \| go (\w+) \| cycles (\d+) \| "
                         r"avg idleness ([\d.]+ s|-)")


def last_config_path():
    return os.environ.get("PATROLLING_SIM_GUI_CONFIG") or os.path.join(
        os.path.expanduser("~"), ".config", "patrolling_sim", "last_config.yaml")


class LauncherApp:
    FIELDS = [  # (key, label, kind, choices)
        ("map", "Map", "combo", None),
        ("robots", "N. Robots", "combo", ["1", "2", "4", "6", "8", "10", "12"]),
        ("alg", "Algorithm", "combo", None),
        ("loc", "Localization", "combo", list(LOC_MODES)),
        ("nav", "Navigation", "combo", list(NAV_MODES)),
        ("gwait", "Goal wait (s)", "combo", ["0", "3", "10"]),
        ("comm_delay", "Comm. delay (s)", "combo", ["0", "0.2", "1"]),
        ("speedup", "Speed-up", "combo", ["1", "2", "4", "8"]),
        ("timeout", "Timeout (sim s)", "combo", ["0", "300", "600", "1800"]),
        # scenario (docs/scenarios.md): any --comm / --attrition spec can be typed in
        ("comm", "Communication", "combo", ["perfect", "bernoulli:p=0.1",
                                            "ge:p_good=0,p_bad=0.8,to_bad=0.05,to_good=0.5",
                                            "range:r=10,los=true"]),
        ("attrition", "Failures", "combo", ["none", "1@300", "1@300+300",
                                            "random:rate=0.5,min_team=2"]),
        # read by the algorithms that take a policy file (POLICY), ignored by the others
        ("policy", "Policy file", "file", None),
    ]

    def __init__(self, root, script, initial=None):
        import tkinter as tk
        from tkinter import ttk
        self.root = root
        self.script = script
        self.proc = None
        self.run_cfg = None       # the running experiment's temporary configuration file
        # the reader thread only fills this queue; Tk is touched from the main loop alone
        self.events = queue.Queue()
        root.title("MRP Experiment Launcher")
        try:
            ttk.Style().theme_use("alt")
        except tk.TclError:
            pass
        cfg = initial or self._load_last()
        choices = {"map": paths.available_maps(), "alg": sorted(REGISTRY)}
        self.vars = {}
        frm = ttk.Frame(root, padding=8)
        frm.grid(sticky="nsew")
        for row, (key, label, kind, opts) in enumerate(self.FIELDS):
            ttk.Label(frm, text=label).grid(row=row, column=0, sticky="w", pady=2)
            var = tk.StringVar(value=self._fmt(getattr(cfg, key)))
            if kind == "file":
                w = ttk.Entry(frm, textvariable=var, width=20)
                ttk.Button(frm, text="...", width=3,
                           command=lambda k=key: self.choose_file(k)).grid(row=row, column=2)
            else:
                w = ttk.Combobox(frm, textvariable=var, values=opts or choices[key], width=18)
            w.grid(row=row, column=1, sticky="ew", pady=2)
            self.vars[key] = var
        row = len(self.FIELDS)
        buttons = ttk.Frame(frm)
        buttons.grid(row=row, column=0, columnspan=2, pady=6)
        self.start_btn = ttk.Button(buttons, text="Start Experiment", command=self.start)
        self.start_btn.grid(row=0, column=0, padx=4)
        self.stop_btn = ttk.Button(buttons, text="Stop Experiment", command=self.stop,
                                   state="disabled")
        self.stop_btn.grid(row=0, column=1, padx=4)
        self.status = tk.StringVar(value="idle")
        self.progress = tk.StringVar(value="sim time -   cycles -   avg idleness -")
        ttk.Label(frm, textvariable=self.status, foreground="#1f4e8c").grid(
            row=row + 1, column=0, columnspan=2, sticky="w")
        ttk.Label(frm, textvariable=self.progress).grid(row=row + 2, column=0, columnspan=2,
                                                        sticky="w")
        self.log = tk.Text(frm, height=8, width=60, state="disabled")
        self.log.grid(row=row + 3, column=0, columnspan=2, sticky="nsew")
        root.protocol("WM_DELETE_WINDOW", self.close)

    @staticmethod
    def _fmt(v):
        if isinstance(v, float) and v == int(v):
            return str(int(v))
        return "" if v is None else str(v)

    def _load_last(self):
        path = last_config_path()
        if os.path.isfile(path):
            try:
                return load_config_file(path)
            except PatrolInputError as e:
                sys.stderr.write(f"start_experiments.py: warning: ignoring {e}\n")
        return ExperimentConfig(map="grid", robots=4, alg="CGG", loc="fake_localization",
                                timeout=300.0, speedup=4.0)

    def choose_file(self, key):
        """A file chooser for field ``key`` (a policy file: ``.npz``)."""
        from tkinter import filedialog
        start = self.vars[key].get().strip()
        start = os.path.abspath(os.path.expanduser(start)) if start else \
            paths.policy_file("default")
        path = filedialog.askopenfilename(
            parent=self.root, title="Policy file", initialdir=os.path.dirname(start),
            filetypes=[("policy files", "*.npz"), ("all files", "*")])
        if path:
            self.vars[key].set(path)

    def current_config(self):
        values = {k: v.get().strip() for k, v in self.vars.items()}
        if values.get("policy"):       # the child and the remembered file need no cwd
            values["policy"] = os.path.abspath(os.path.expanduser(values["policy"]))
        return self._load_last().updated(values, "GUI")

    def append(self, line):
        self.log.configure(state="normal")
        self.log.insert("end", line + "\n")
        self.log.see("end")
        self.log.configure(state="disabled")

    def start(self):
        if self.proc is not None:
            return
        try:
            cfg = self.current_config().validate()
        except PatrolInputError as e:
            self.status.set(f"error: {e}")
            return
        path = last_config_path()
        os.makedirs(os.path.dirname(path), exist_ok=True)
        cfg.save(path)
        # the run's own configuration file; the runner copies it into the results
        # (_config.yaml), and the reader removes it once the run has ended
        fd, run_cfg = tempfile.mkstemp(prefix="patrol_gui_", suffix=".yaml")
        os.close(fd)
        cfg.save(run_cfg)
        self.run_cfg = run_cfg
        self.proc = subprocess.Popen([sys.executable, self.script, "--headless", "--config",
                                      run_cfg], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, text=True, bufsize=1,
                                     start_new_session=True)
        self.status.set(f"running {cfg.map_name}, {cfg.robots} robots, {cfg.alg}")
        self.start_btn.configure(state="disabled")
        self.stop_btn.configure(state="normal")
        threading.Thread(target=self._reader, args=(self.proc, run_cfg), daemon=True).start()
        self.root.after(POLL_MS, self._poll)

    def _reader(self, proc, run_cfg):
        for line in proc.stdout:
            self.events.put(("line", line.rstrip("\n")))
        proc.wait()
        try:
            os.unlink(run_cfg)
        except OSError:
            pass
        self.events.put(("exit", proc.returncode))

    def _poll(self):
        """Main-loop side of the reader: drain its queue (Tk is not thread-safe)."""
        try:
            while True:
                kind, value = self.events.get_nowait()
                if kind == "line":
                    self._on_line(value)
                else:
                    self._on_exit(value)
                    return
        except queue.Empty:
            pass
        self.root.after(POLL_MS, self._poll)

    def _on_line(self, line):
        m = PROGRESS_RE.search(line)
        if m:
            sim, go, cycles, avg = m.groups()
            self.progress.set(f"sim time {float(sim):.0f} s   cycles {cycles}   "
                              f"avg idleness {avg}" + ("" if go == "yes" else "   (waiting GO)"))
        else:
            self.append(line)

    def _on_exit(self, code):
        self.status.set(f"finished (exit {code})")
        self.proc = None
        self.start_btn.configure(state="normal")
        self.stop_btn.configure(state="disabled")

    def stop(self):
        if self.proc is not None and self.proc.poll() is None:
            self.status.set("stopping...")
            os.kill(self.proc.pid, signal.SIGINT)

    def close(self):
        self.stop()
        if self.proc is not None:
            try:
                self.proc.wait(timeout=90)
            except subprocess.TimeoutExpired:
                self.proc.kill()
        self.root.destroy()


def run_gui(script, initial=None):
    try:
        import tkinter as tk
    except ImportError:
        raise PatrolInputError("the GUI needs Tk: apt-get install python3-tk") from None
    try:
        root = tk.Tk()
    except tk.TclError as e:
        raise PatrolInputError(f"cannot open the GUI window ({e})") from None
    LauncherApp(root, script, initial)
    root.mainloop()
    return 0
