"""The ``sonarcal`` command line: argument parsing and printing only; all work is in calib_core."""
