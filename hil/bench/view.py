"""What the ``bench`` fixture gives a suite: the bench's public surface, with no way round the guard.

Suites only touch the bench fixture (DESIGN).  :func:`suite_view` wraps a bench in an object that has exactly
the names its family's face declares (a Protocol: :class:`hil.bench.faces.BenchView`, extended by the family,
e.g. :class:`hil.families.fbs.faces.Bench`); the bench itself lives in the methods' closure, so ``bench.raw``,
``bench.io.inner`` or a transport's private ``_write_*`` are not there to call (issue 15).  The PLC object's ``io``
is the guarded I/O (:func:`guarded_io`: the members of the guard's ``FACE`` Protocol and nothing else), and
fault injectors are wrapped the same way (:class:`hil.bench.faces.FaultInjector`).
"""

from __future__ import annotations

import typing
from typing import Any

from hil.bench.faces import BenchView, FaultInjector, Faults, members


def _view(title: str, members: dict[str, Any]) -> Any:
    namespace: dict[str, Any] = {"__slots__": (), "__repr__": lambda self: f"<{title}>"}
    for name, member in members.items():
        if callable(member) and not isinstance(member, property):
            namespace[name] = (lambda fn: lambda self, *a, **k: fn(*a, **k))(member)
        else:
            namespace[name] = member
    namespace["__setattr__"] = _frozen
    return type(title.replace(" ", "_"), (), namespace)()


def _frozen(self: object, name: str, value: object) -> None:
    raise AttributeError(f"a suite cannot change the bench ({name})")


def _has(obj: Any, name: str) -> bool:
    return hasattr(type(obj), name) or name in getattr(obj, "__dict__", {})


def _forward(obj: Any, face: type, skip: tuple[str, ...] = ()) -> dict[str, Any]:
    """The members of ``face`` that ``obj`` has, each read from ``obj`` when used (``obj`` stays in the closure)."""
    out: dict[str, Any] = {}
    for name, is_method in members(face).items():
        if name in skip or not _has(obj, name):
            continue
        if is_method:
            out[name] = (lambda n: lambda *a, **k: getattr(obj, n)(*a, **k))(name)
        else:  # a value or property (description, limits, has_cpu_clock …)
            out[name] = property((lambda n: lambda self: getattr(obj, n))(name))
    return out


def guarded_io(guard: Any) -> Any:
    """What a suite may hold of the PLC's I/O: the members of the family's ``FACE`` Protocol on its guarded link
    (its reads, and writes through the guard)."""
    return _view(f"guarded I/O of {guard.description}", _forward(guard, type(guard).FACE))


def suite_view(bench: Any) -> Any:
    """The bench as a suite sees it: the members of its family's ``FACE`` (default :class:`BenchView`)."""
    face = getattr(type(bench), "FACE", BenchView)
    found = _forward(bench, face, skip=("faults",))
    if "unreachable_reason" not in found and hasattr(bench, "raw"):
        found["unreachable_reason"] = lambda name: bench.raw.unreachable_reason(name)
    if "faults" in members(face) and hasattr(bench, "faults"):
        faults_face = _returns(face, "faults") or Faults
        found["faults"] = property(lambda self: faults_view(bench.faults, faults_face))
    return _view("bench", found)


def _returns(face: type, name: str) -> type | None:
    """The type a Protocol's property ``name`` returns (None when it cannot be resolved at run time)."""
    for klass in face.__mro__:
        member = vars(klass).get(name)
        if isinstance(member, property) and member.fget is not None:
            try:
                hint = typing.get_type_hints(member.fget).get("return")
            except NameError:
                return None
            return hint if isinstance(hint, type) else None
    return None


def faults_view(faults: Any, face: type = Faults) -> Any:
    """The fault injectors: ``get`` and ``unavailable``, and each injector ``face`` names as a property (by the
    profile's ``[faults.<name>]``), every injector wrapped by :func:`injector_view`."""
    def get(name: str) -> Any:
        injector = faults.get(name)
        return None if injector is None else injector_view(injector)
    found: dict[str, Any] = {"get": get, "unavailable": lambda name: faults.unavailable(name)}
    for name, is_method in members(face).items():
        if not is_method:
            found[name] = property((lambda n: lambda self: get(n))(name))
    return _view("bench faults", found)


def injector_view(injector: FaultInjector) -> Any:
    return _view(f"{injector.kind} injector", _forward(injector, FaultInjector))


__all__ = ["guarded_io", "suite_view"]
