"""The plant's run: clock, parameters, watchdog and the command source."""
