"""Running scenarios: scenario files, the in-process engine, the node-graph runner, outputs."""
