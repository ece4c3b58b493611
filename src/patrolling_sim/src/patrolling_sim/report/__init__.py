"""Results analysis: load experiment result files, summary table, significance tests,
figures and a self-contained HTML report (``scripts/report.py``). Pure Python: pandas,
scipy, matplotlib (Agg canvas); no ROS import."""
