"""One module per sonarcal command: ``add_parser(sub)`` and its ``run(args)``."""
