"""HydroBench parameter sweeps and robustness studies (`hbench sweep`).

A study file (TOML) names the FMU, the scenario, the parameters to vary and the metrics
to compute; the runner evaluates every point on a Dask cluster (a local one over all
cores by default, or the one at `--scheduler`), keeps one record per point keyed by a
stable point id so an interrupted study resumes without recomputing finished points, and
writes a CSV table, a sensitivity ranking and plots.

Modules:
- `study`: parse and check a study file (errors name the file, line and field);
- `sampling`: grid, random and Latin-hypercube points with seeds;
- `scenario`: the input table and metric windows (`hbench simulate --inputs-only`);
- `evaluate`: what a worker runs: one FMU simulation and its metrics (numpy and fmpy only);
- `runner`: the result store, resume, and the serial and Dask executions;
- `report`: results.csv, sensitivity.csv and the plots;
- `cli`: the command line (`python -m sweep`, which `hbench sweep` runs).
"""
