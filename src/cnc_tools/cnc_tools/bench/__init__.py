"""Benchmarks of ``cnc-contour bench NAME``: figures measured side by side in one run.

A bench is a function ``(options) -> exit code`` listed by name in
:data:`cnc_tools.bench.registry.BENCHES`. It measures, prints a table, returns 0 once every
measurement ran (a goal that is not met is reported, not an error), and
writes its figures as JSON to ``options.json`` when that is set. The options
are those of the ``bench`` subcommand (:mod:`cnc_tools.cli.bench`):
``name``, ``quick`` (a shorter run), ``json`` and ``out`` (a folder for run
files, or None).

Adding a bench: a module in this package (speed) or in ``reproductions/``
(a paper's table) with the function, and one line in :mod:`cnc_tools.bench.registry`.
"""
