"""The Tk launcher's policy file field, on a virtual screen: it shows the remembered file,
hands the file it is given (as an absolute path) to the experiment it starts, takes a file
from its chooser, and a policy file that does not load stops the start with a one-line
error. The experiment is a stand-in script that reports the configuration it was given.
One test, one Tk window (Tk keeps its display connection after the window is destroyed:
the virtual display is one per test process, tests/ros/conftest.py)."""
import os
import shutil
import sys
import textwrap

import yaml

from tk_pump import pump

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))
SHIPPED = os.path.join(ROOT, "policies", "slots_bc.npz")

#: stands in for start_experiments.py: prints the arguments and the configuration's policy
FAKE_RUNNER = textwrap.dedent("""\
    import sys
    import yaml
    cfg = yaml.safe_load(open(sys.argv[sys.argv.index("--config") + 1]))
    print("args", " ".join(sys.argv[1:]))
    print("alg", cfg.get("alg"), "policy", cfg.get("policy"))
    """)


def test_policy_field(tmp_path, xvfb, monkeypatch):
    """The three checks below on one launcher (module docstring)."""
    monkeypatch.setenv("DISPLAY", xvfb)
    last = tmp_path / "last_config.yaml"
    monkeypatch.setenv("PATROLLING_SIM_GUI_CONFIG", str(last))
    monkeypatch.chdir(tmp_path)
    from patrolling_sim.runner.config import ExperimentConfig
    from patrolling_sim.runner.gui import LauncherApp
    ExperimentConfig(map="grid", robots=2, alg="POLICY", loc="fake_localization", timeout=60,
                     speedup=4, policy=SHIPPED, results_dir=str(tmp_path / "r")).save(str(last))
    script = tmp_path / "fake_runner.py"
    script.write_text(FAKE_RUNNER)
    import tkinter as tk
    root = tk.Tk()
    app = LauncherApp(root, str(script))
    try:
        check_reaches_the_experiment(app, root, tmp_path)
        check_chooser_fills_the_field(app, tmp_path, monkeypatch)
        check_bad_file_is_a_one_line_error(app, tmp_path)
    finally:
        if app.proc is not None:
            app.proc.kill()
            app.proc.wait(timeout=30)
        root.destroy()


def _log(app):
    return app.log.get("1.0", "end")


def check_reaches_the_experiment(app, root, tmp_path):
    assert app.vars["policy"].get() == SHIPPED            # the remembered file is shown
    shutil.copy(SHIPPED, tmp_path / "mine.npz")
    app.vars["policy"].set("mine.npz")                     # relative to the working folder
    app.start_btn.invoke()
    assert app.proc is not None, app.status.get()
    pump(root, lambda: app.proc is None, 60, "the experiment's end",
         lambda: f"status '{app.status.get()}'")
    assert app.status.get() == "finished (exit 0)", app.status.get()
    want = str(tmp_path / "mine.npz")
    assert f"alg POLICY policy {want}" in _log(app), _log(app)
    remembered = yaml.safe_load(open(os.environ["PATROLLING_SIM_GUI_CONFIG"]))
    assert remembered["policy"] == want


def check_chooser_fills_the_field(app, tmp_path, monkeypatch):
    from tkinter import filedialog
    asked = {}

    def fake_dialog(**kw):
        asked.update(kw)
        return str(tmp_path / "chosen.npz")
    monkeypatch.setattr(filedialog, "askopenfilename", fake_dialog)
    app.choose_file("policy")
    assert app.vars["policy"].get() == str(tmp_path / "chosen.npz")
    assert asked["initialdir"] == str(tmp_path)             # beside the current file
    monkeypatch.setattr(filedialog, "askopenfilename", lambda **kw: "")   # cancelled
    app.choose_file("policy")
    assert app.vars["policy"].get() == str(tmp_path / "chosen.npz")


def check_bad_file_is_a_one_line_error(app, tmp_path):
    (tmp_path / "bad.npz").write_text("not a policy")
    app.vars["policy"].set(str(tmp_path / "bad.npz"))
    app.start_btn.invoke()
    status = app.status.get()
    assert app.proc is None and status.startswith("error: ") and "\n" not in status, status
    assert "bad.npz" in status and "not a .npz archive" in status, status
    assert str(app.start_btn["state"]) == "normal"
