"""Paper 001: neuro-contouring (contour-error estimator, online neural compensator, baselines) reproduced."""
