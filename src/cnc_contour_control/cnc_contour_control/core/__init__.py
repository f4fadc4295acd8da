"""The kernel every other layer stands on: errors, validated configs and parameters, units, the lockstep tick,
topics and the stage pipeline, the shared lag and force primitives."""
