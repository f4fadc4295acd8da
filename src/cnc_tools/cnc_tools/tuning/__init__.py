"""Tuning: scenario parameters chosen by differential evolution (``cnc-contour tune``, ``docs/tuning.md``)."""
