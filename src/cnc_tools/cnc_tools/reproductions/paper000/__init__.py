"""Paper 000: fuzzy friction compensation against the incremental PID (Tables 4-5, Figs. 8-12)."""
