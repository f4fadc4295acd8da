"""A per-tick record: a plain ``__slots__`` class (cheap to fill every tick) that prints its slots (ROS-free)."""
from __future__ import annotations


class SlotsRecord:
    """Base of the per-tick records (:class:`~cnc_contour_control.laws.base.LawSample`, ...): a repr of the slots.

    A subclass declares its fields in ``__slots__``; nothing else is added, so
    reading and writing them costs what it costs on a plain slots class.
    """

    __slots__: tuple[str, ...] = ()

    def __repr__(self) -> str:
        values = ", ".join(f"{name}={getattr(self, name)!r}" for name in self.__slots__)
        return f"{type(self).__name__}({values})"
