"""The registry of feedback laws: a law is chosen by name and built from a params mapping.

A feedback law turns the following error (in the law's length unit, BLU for
paper 000) into a feedback command in drive units (DAC for paper 000),
before the servo adds feedforward and compensation and saturates.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Protocol, runtime_checkable

from cnc_contour_control.config import require_choice


@runtime_checkable
class FeedbackLaw(Protocol):
    """A discrete feedback law with internal state."""

    def reset(self) -> None:
        """Clear the internal state (as at start-up)."""

    def step(self, error: float, dt_s: float) -> float:
        """One sample: ``error`` in law length units, ``dt_s`` the period [s].

        Returns the feedback command in drive units, not yet saturated by the servo.
        """


#: A law factory: params mapping -> law (validates the params, unknown keys refused).
LawFactory = Callable[[Mapping[str, Any]], FeedbackLaw]

#: Feedback laws by name.
LAWS: dict[str, LawFactory] = {}


def register_law(name: str) -> Callable[[LawFactory], LawFactory]:
    """Decorator registering ``factory`` under ``name`` in :data:`LAWS`.

    Raises
    ------
    ValueError
        If ``name`` is already taken.
    """

    def decorate(factory: LawFactory) -> LawFactory:
        if name in LAWS:
            raise ValueError(f"feedback law {name!r} is already registered")
        LAWS[name] = factory
        return factory

    return decorate


def make_law(name: str, params: Mapping[str, Any] | None = None) -> FeedbackLaw:
    """Build the law ``name`` from ``params``; an unknown name lists the valid ones."""
    require_choice("law", name, LAWS)
    return LAWS[name](params or {})
