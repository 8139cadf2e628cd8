"""The lab: measurement rather than product. ``warp-cloth bench`` (wall time of whole runs, bench.py, with
its mesh cases in bench_meshes.py and Newton's solvers timed alike in newton_compare.py) and ``warp-cloth
study`` (what accuracy costs in time, study.py). Nothing outside this package imports it: the command line
loads a lab command's module by name when that command is asked for (``cli.LAB_COMMANDS``)."""
