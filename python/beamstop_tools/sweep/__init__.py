"""Parameter sweeps of beamstop FMUs on Dask (issue 11).

`python -m beamstop_tools.sweep FMU --param NAME=FROM:TO:POINTS ...` (scripts/sweep)
drives an FMU through fmpy on dask.distributed workers over a grid of one or
two parameters and writes DIR/points.parquet and plots. The modules, one job
each:

- `fmu`: what an FMU offers (parameters with ranges, forcing frequency,
  stops and their event counters), read from its modelDescription.xml and
  its resources/scene.json;
- `expr`: arithmetic expressions in --set and grid ends (`-2e-4*shaker.omega**2`);
- `spec`: the sweep's settings, checked, and its grid of points;
- `measures`: what is measured from a recorded point (period, peak, maxima);
- `runner`: runs points on a worker, one FMU instance per worker process;
- `store`: finished tasks as Parquet parts (resume), the final table;
- `engine`: the Dask client, the tasks, the progress bar;
- `plots`: generic PNGs of a sweep; `figures`: the papers' figures (VSM12, RMTM, WB00);
- `bench`: points per second and overhead per point, 1 and 2 workers and an
  external scheduler.
"""
