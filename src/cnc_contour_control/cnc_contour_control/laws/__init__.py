"""Feedback laws of the servo: the seam (:mod:`.base`) and the registry :data:`LAWS` (:mod:`.registry`)."""
from __future__ import annotations

from cnc_contour_control.laws.base import FeedbackLaw, LawOutput, LawSample
from cnc_contour_control.laws.registry import LAWS, LawEntry, law_config, law_config_class, make_law

__all__ = ["LAWS", "FeedbackLaw", "LawEntry", "LawOutput", "LawSample", "law_config", "law_config_class",
           "make_law"]
