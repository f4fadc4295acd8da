"""Motion planning: path geometry, G-code and programs, look-ahead blending, feed planning, interpolation and
feed override."""
