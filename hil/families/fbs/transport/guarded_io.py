"""What a suite may hold of the PLC's I/O: the guarded operations and nothing else.

:func:`guarded_io` wraps a :class:`~hil.families.fbs.transport.guard.GuardedTransport` in an object whose only
attributes are the guarded reads and writes (and FATEK commands 41/42 through the guard).  The transport it wraps
is held in the methods' closure, not in an attribute: there is no ``.inner``, ``.raw`` or ``_write_*`` to reach
round the guard (issue 15).
"""

from __future__ import annotations

from typing import Any

PUBLIC = ("read", "read_words", "read_bits", "read_many", "write", "write_words", "write_bits", "write_many",
          "status", "unreachable_reason", "require", "budget", "set_running", "bit_action")


def guarded_io(guard: Any) -> Any:
    """The suite-facing I/O over ``guard``."""

    def make(name: str):  # noqa: ANN202
        def method(self, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
            return getattr(guard, name)(*args, **kwargs)
        method.__name__ = name
        method.__doc__ = getattr(type(guard), name).__doc__
        return method

    namespace: dict[str, Any] = {name: make(name) for name in PUBLIC}
    namespace["__slots__"] = ()
    namespace["__doc__"] = f"Guarded I/O of {guard.description}: reads, and writes the profile allows."
    namespace["description"] = property(lambda self: guard.description)
    namespace["limits"] = property(lambda self: guard.limits)
    namespace["requests_per_read"] = property(lambda self: guard.requests_per_read)
    namespace["__repr__"] = lambda self: f"<guarded I/O of {guard.description}>"
    namespace["__setattr__"] = _frozen
    return type("GuardedIO", (), namespace)()


def _frozen(self, name: str, value: object) -> None:  # noqa: ANN001
    raise AttributeError(f"the guarded I/O cannot be changed ({name})")


__all__ = ["guarded_io"]
