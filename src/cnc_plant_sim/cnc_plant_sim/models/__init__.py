"""Plant models of the feed drives, their friction and faults, and the registry that builds them."""
