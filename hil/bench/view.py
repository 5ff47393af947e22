"""What the ``bench`` fixture gives a suite: the bench's public surface, with no way round the guard.

Suites only touch the bench fixture (DESIGN).  :func:`suite_view` wraps a bench in an object that has exactly
the suite-facing names (``plc``, ``wait``, ``settle``, ``faults``, ``cannot_reach``, ``profile``, ``time`` …);
the bench itself lives in the methods' closure, so ``bench.raw``, ``bench.io.inner`` or a transport's private
``_write_*`` are not there to call (issue 15).  The PLC object's ``io`` is the guarded I/O (:func:`guarded_io`:
the guard's public operations and nothing else, whatever the family), and fault injectors are wrapped the same way.
"""

from __future__ import annotations

from typing import Any

#: callables and values a suite may use, when the bench has them
METHODS = ("wait", "settle", "cannot_reach", "end_test", "power_cycle", "identity", "unreachable_reason")
VALUES = ("plc", "profile", "time", "settings", "is_emulator", "target", "name", "allow_destructive")
INJECTOR = ("open", "repair", "inject", "clear", "openable")


def _view(title: str, members: dict[str, Any]) -> Any:
    namespace: dict[str, Any] = {"__slots__": (), "__repr__": lambda self: f"<{title}>"}
    for name, member in members.items():
        if callable(member) and not isinstance(member, property):
            namespace[name] = (lambda fn: lambda self, *a, **k: fn(*a, **k))(member)
        else:
            namespace[name] = member
    namespace["__setattr__"] = _frozen
    return type(title.replace(" ", "_"), (), namespace)()


def _frozen(self, name: str, value: object) -> None:  # noqa: ANN001
    raise AttributeError(f"a suite cannot change the bench ({name})")


def guarded_io(guard: Any) -> Any:
    """What a suite may hold of the PLC's I/O: the names the family's guarded link lists in ``PUBLIC`` (its
    reads, and writes through the guard).  The link lives in the methods' closure, not in an attribute: there is
    no ``.inner``, ``.raw`` or ``_write_*`` to reach round the guard."""
    members: dict[str, Any] = {}
    for name in type(guard).PUBLIC:
        member = getattr(type(guard), name, None)
        if callable(member):
            members[name] = (lambda n: lambda *a, **k: getattr(guard, n)(*a, **k))(name)
        else:  # a value or property of the link (description, limits, has_cpu_clock …)
            members[name] = property((lambda n: lambda self: getattr(guard, n))(name))
    return _view(f"guarded I/O of {guard.description}", members)


def suite_view(bench: Any) -> Any:
    """The bench as a suite sees it."""
    members: dict[str, Any] = {}
    for name in METHODS:
        if hasattr(type(bench), name) or hasattr(bench, name):
            members[name] = (lambda n: lambda *a, **k: getattr(bench, n)(*a, **k))(name)
    for name in VALUES:
        if hasattr(type(bench), name) or name in getattr(bench, "__dict__", {}):
            members[name] = property((lambda n: lambda self: getattr(bench, n))(name))
    if "unreachable_reason" not in members and hasattr(bench, "raw"):
        members["unreachable_reason"] = lambda name: bench.raw.unreachable_reason(name)
    if hasattr(bench, "faults"):
        members["faults"] = property(lambda self: faults_view(bench.faults))
    return _view("bench", members)


def faults_view(faults: Any) -> Any:
    def get(name: str) -> Any:
        injector = faults.get(name)
        return None if injector is None else injector_view(injector)
    members: dict[str, Any] = {"get": get, "unavailable": lambda name: faults.unavailable(name)}
    for name in getattr(faults, "names", ()):  # the family's injectors by name
        members[name] = property((lambda n: lambda self: get(n))(name))
    return _view("bench faults", members)


def injector_view(injector: Any) -> Any:
    members: dict[str, Any] = {n: getattr(injector, n) for n in INJECTOR if hasattr(injector, n)}
    members["kind"] = property(lambda self: injector.kind)
    return _view(f"{injector.kind} injector", members)


__all__ = ["guarded_io", "suite_view"]
