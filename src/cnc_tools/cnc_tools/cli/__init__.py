"""The ``cnc-contour`` command: one module per subcommand, listed in :mod:`cnc_tools.cli.registry`."""
