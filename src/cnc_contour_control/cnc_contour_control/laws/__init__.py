"""Feedback laws of the servo, chosen by name from :data:`LAWS`."""
from __future__ import annotations

from cnc_contour_control.laws.registry import (
    LAWS,
    FeedbackLaw,
    LawFactory,
    make_law,
    register_law,
)

# Importing a law module registers its laws.
from cnc_contour_control.laws import pid  # noqa: E402,F401
from cnc_contour_control.laws import fuzzy  # noqa: E402,F401

__all__ = ["LAWS", "FeedbackLaw", "LawFactory", "make_law", "register_law"]
