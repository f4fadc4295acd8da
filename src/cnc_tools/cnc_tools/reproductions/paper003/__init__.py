"""Paper 003 (optimal velocity-loop gains against circular-test radius errors): data, runs, bench."""
