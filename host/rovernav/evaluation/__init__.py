"""Evaluation: what the simulator's runs are measured on and how they are judged.

    arenas/    `rovernav arenas`: scenario files drawn from families of arenas, labelled with a
               difficulty and whether they can be solved (draw, families, cellular, difficulty,
               generate, cli)
    trials.py  `rovernav trials`: many missions on many arenas, in parallel, with headline figures
               and a gate; its parts:
    jobs.py      the arenas to run (all or a sample), the jobs, one run in the simulator
    scoring.py   a run's row from its report, the scores (BARN, time), the headlines, the gate
    pool.py      running the jobs (serially, or on dask.distributed), and map_runs: the process
                 pool the benchmarks (benchmarks/*.py) run their runs in
    tables.py    trials.csv, trials.json, trials.md and the gallery of failed runs
    report.py  one run's report: report.json, summary.png, the video, the lines printed of it

It stands above the simulator (rovernav.sim, the world missions run in): evaluation imports sim,
never the other way round (tests/test_imports.py checks it); `rovernav sim`'s front end
(rovernav.sim.cli, a unit of its own) writes its run's report with report.py.
"""
