"""Reproductions of the papers, one folder per paper (data, runs, tables)."""
