"""Paper 002: periodic disturbance cancelling (the reproduction bench ``cnc-contour bench paper002``)."""
