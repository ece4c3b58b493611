"""The Tk launcher on a virtual screen, and recorded runs.

- The GUI, under Xvfb, is driven through its own widgets: it shows the remembered
  configuration, starts a short experiment, shows live progress, is stopped with its Stop
  button, and the run's result files are complete; a screenshot of the screen is not blank.
- ``--record`` on a 60 s (sim) run leaves a video that OpenCV decodes frame by frame.
"""
import glob
import os
import subprocess
import sys


from rosenv import ros_env
from tk_pump import pump
from test_experiments import START, check_files, finish, prefixes, start

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))


def test_recorded_run_is_a_playable_video(tmp_path):
    p = start(["--map", "grid", "--robots", "1", "--alg", "CR", "--loc", "fake_localization",
               "--timeout", "60", "--speedup", "4", "--record", "--record-period", "1"],
              tmp_path)
    rc, out = finish(p, 300)
    assert rc == 0, out[-3000:]
    (prefix,) = prefixes(tmp_path)
    check_files(prefix)
    snaps = sorted(glob.glob(prefix + "_snapshots/*.png"))
    assert len(snaps) >= 60, len(snaps)          # >= one per sim second of the run
    video = prefix + "_run.mp4"
    assert os.path.isfile(video) and "video" in out, out[-2000:]
    import cv2
    from patrolling_sim.runner.video import count_frames
    assert count_frames(video) == len(snaps)
    first = cv2.imread(snaps[0])
    last = cv2.imread(snaps[-1])
    assert first.std() > 10                      # map, robot and graph drawn, not blank
    assert (first != last).any()                 # the robot moved between first and last


def test_gui_starts_and_stops_an_experiment(tmp_path, xvfb, monkeypatch):
    for k, v in ros_env().items():
        monkeypatch.setenv(k, v)
    monkeypatch.setenv("DISPLAY", xvfb)
    last = tmp_path / "last_config.yaml"
    monkeypatch.setenv("PATROLLING_SIM_GUI_CONFIG", str(last))
    from patrolling_sim.runner.config import ExperimentConfig, load_config_file
    from patrolling_sim.runner.gui import LauncherApp
    results = tmp_path / "results"
    ExperimentConfig(map="grid", robots=2, alg="CR", loc="fake_localization", timeout=0,
                     speedup=4, results_dir=str(results)).save(str(last))
    import tkinter as tk
    root = tk.Tk()
    try:
        app = LauncherApp(root, START)
        # the remembered configuration is shown
        assert app.vars["map"].get() == "grid" and app.vars["robots"].get() == "2"
        assert app.vars["alg"].get() == "CR" and app.vars["speedup"].get() == "4"
        app.vars["alg"].set("CGG")                    # edit a field, then Start
        app.start_btn.invoke()
        assert str(app.stop_btn["state"]) == "normal"

        def state():
            return f"status '{app.status.get()}', progress '{app.progress.get()}'"

        def sim_time():
            words = app.progress.get().split()
            return float(words[2]) if len(words) > 2 and words[2] != "-" and \
                "waiting" not in app.progress.get() else -1.0

        # the progress shows the simulator's clock, a few seconds ahead of the time since GO
        pump(root, lambda: sim_time() >= 36.0, 180, "progress after GO", state)
        assert "cycles" in app.progress.get() and "avg idleness" in app.progress.get()
        shot = tmp_path / "gui.png"
        subprocess.run(["import", "-display", xvfb, "-window", "root", str(shot)],
                       check=True, timeout=30)
        import cv2
        img = cv2.imread(str(shot))
        assert img is not None and img.std() > 5, "blank screenshot"
        app.stop_btn.invoke()                          # Stop: orderly shutdown
        pump(root, lambda: app.proc is None, 120, "the run's end", state)
        assert app.status.get().startswith("finished"), app.status.get()
        assert not os.path.exists(app.run_cfg), "the run's temporary configuration was left"
        assert str(app.start_btn["state"]) == "normal"
    finally:
        if getattr(app, "proc", None) is not None:
            app.proc.terminate()                       # the runner's orderly SIGTERM path
            try:
                app.proc.wait(timeout=90)
            except subprocess.TimeoutExpired:
                app.proc.kill()
        root.destroy()
    (prefix,) = prefixes(results)
    info, rows = check_files(prefix)
    assert info["algorithm"] == "CGG" and info["team_size"] == 2
    # the original's CGG walks a 274 m route forth and back: after 30 s the two robots may
    # not have revisited any vertex yet (no idleness sample), but they have visited several
    visits = open(prefix + "_visits.csv").read().splitlines()[1:]
    assert info["sim_duration"] >= 30.0 and len(visits) >= 4, visits
    assert load_config_file(str(last)).alg == "CGG"    # remembered for next time
