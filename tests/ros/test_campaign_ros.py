"""A small ROS-mode campaign: grid, 2 algorithms, 2 robots, 60 s, two experiments
at a time on a LocalCluster, each with its own ROS master; the table lists both runs."""
import os
import subprocess

import pandas as pd
import yaml

from rosenv import ros_env

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SCRIPT = os.path.join(ROOT, "scripts", "campaign.py")


def test_ros_campaign_two_at_a_time(tmp_path):
    camp = {"name": "ros_small", "mode": "ros",
            "fixed": {"map": "grid", "robots": 2, "loc": "fake_localization", "timeout": 60,
                      "speedup": 3},
            "grid": {"alg": ["CR", "CGG"]}}
    path = tmp_path / "ros.yaml"
    path.write_text(yaml.safe_dump(camp))
    out = tmp_path / "out"
    p = subprocess.run(["/usr/bin/python3", SCRIPT, str(path), "--workers", "2", "--out",
                        str(out), "--no-report"], capture_output=True, text=True,
                       env=ros_env(), timeout=900, stdin=subprocess.DEVNULL)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    df = pd.read_csv(out / "runs.csv")
    assert sorted(df["alg"]) == ["CGG", "CR"]
    assert (df["status"] == "TIMEOUT").all(), df[["alg", "status"]]
    assert (df["sim_duration"] >= 60).all()
    assert (df["total_visits"] > 0).all()
    for prefix in df["prefix"]:
        for suf in ("_idleness.csv", "_info.csv", "_results.txt", "_timeresults.csv"):
            assert os.path.isfile(out / (prefix + suf)), prefix + suf
    # both experiments ran at the same time (one master each, two workers)
    state = [yaml.safe_load(open(out / "state" / f)) for f in os.listdir(out / "state")]
    (s0, e0), (s1, e1) = [(s["provenance"]["start"], s["provenance"]["end"]) for s in state]
    assert s0 < e1 and s1 < e0, state
