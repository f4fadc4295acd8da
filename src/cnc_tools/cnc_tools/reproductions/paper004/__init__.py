"""Paper 004: cutting-force regulation in turning through a quantised feed override (SMC, adaptive, PI) reproduced."""
