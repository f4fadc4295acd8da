"""The graph wiring: per-stage parameters, the cross-axis stage, and the parameter files of a node graph."""
