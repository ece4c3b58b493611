"""Campaigns: grids of runs on Dask, resumable, summarised in ``runs.csv``.

- :mod:`~patrolling_sim.campaign.spec`         -- the campaign file and its runs
- :mod:`~patrolling_sim.campaign.tasks`        -- one run (or chunk of runs) in a worker
- :mod:`~patrolling_sim.campaign.run_warnings` -- warnings kept per run
- :mod:`~patrolling_sim.campaign.store`        -- run records and the ``runs.csv`` table
- :mod:`~patrolling_sim.campaign.forkserver`   -- the local workers' process start
- :mod:`~patrolling_sim.campaign.cluster`      -- the Dask cluster: its start, size and workers
- :mod:`~patrolling_sim.campaign.engine`       -- running a campaign
- :mod:`~patrolling_sim.campaign.cli`          -- the ``campaign.py`` command line
"""
