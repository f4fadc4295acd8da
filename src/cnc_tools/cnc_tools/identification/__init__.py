"""Identification of plant parameters from runs."""
