"""Cutting processes (turning, milling) that load the feed drives."""
