"""Watch a run live in Foxglove (or Lichtblick): an embedded foxglove-sdk WebSocket server.

``server`` (the server, its channels, the loopback rule), ``decimate`` (peak-keeping windows),
``feed`` (the suite's messages to channels, the derived streams), ``scene`` (the 3D scene),
``engine`` (an engine run paced to the wall clock), ``ros`` (the ``live`` node: a graph's topics),
``layout`` (the shipped Foxglove layout), ``options`` (the ``--live*`` options), ``client`` and ``watch`` (a
protocol client and a watched run, for tests and ``bench live``). docs/live.md.
"""
