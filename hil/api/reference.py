"""The API reference of :mod:`hil.api`, generated from its docstrings: ``python -m hil.api.reference > docs/api.md``.

A test (tests/test_public_api.py) regenerates it and compares, so docs/api.md never drifts from the code.
"""

from __future__ import annotations

import dataclasses
import enum
import inspect
import sys
from collections.abc import Callable, Iterator
from typing import Any

import hil.api
from hil.bench.faces import members

HEADER = """# hil API reference

Generated from the docstrings of `hil.api` by `python -m hil.api.reference` (do not edit by hand; a test checks
that it is current).  How to use it: docs/writing-tests.md.

"""


def _doc(obj: object) -> str:
    return inspect.cleandoc(obj.__doc__ or "").strip()


def _annotation(value: object) -> str:
    return value if isinstance(value, str) else getattr(value, "__name__", repr(value))


def _signature(fn: Callable[..., Any]) -> str:
    """``(name: type = default, *, …) -> type``, with the annotations as written (not quoted)."""
    parts: list[str] = []
    star = False
    for p in inspect.signature(fn).parameters.values():
        if p.name == "self":
            continue
        if p.kind is p.KEYWORD_ONLY and not star:
            parts.append("*")
            star = True
        prefix = "*" if p.kind is p.VAR_POSITIONAL else "**" if p.kind is p.VAR_KEYWORD else ""
        star = star or p.kind is p.VAR_POSITIONAL
        text = prefix + p.name + (f": {_annotation(p.annotation)}" if p.annotation is not p.empty else "")
        parts.append(text + (f" = {p.default!r}" if p.default is not p.empty else ""))
    returns = inspect.signature(fn).return_annotation
    return f"({', '.join(parts)})" + (f" -> {_annotation(returns)}" if returns is not inspect.Signature.empty else "")


def _public_members(klass: type) -> list[str]:
    """The names of a class's own public methods and properties, in definition order."""
    return [n for n, v in vars(klass).items() if not n.startswith("_") and (callable(v) or isinstance(v, property))]


def _member_names(klass: type) -> list[str]:
    """What the reference lists of ``klass``: a Protocol's members (its ``__call__`` first), a dataclass's fields
    then its methods and properties, or a class's methods and properties — each once."""
    if getattr(klass, "_is_protocol", False):
        names = (["__call__"] if "__call__" in vars(klass) else []) + list(members(klass))
    elif dataclasses.is_dataclass(klass):
        names = [f.name for f in dataclasses.fields(klass)] + _public_members(klass)
    else:
        names = _public_members(klass)
    return list(dict.fromkeys(names))


def _described(text: str, documented: object) -> str:
    """``text`` followed by ``documented``'s docstring on one line, when it has one."""
    doc = _doc(documented)
    return text + (f": {' '.join(doc.split())}" if doc else "")


def _member_line(member: object, name: str) -> str | None:
    """One member's line: a property with what it returns, a method with its signature (None for a value)."""
    if isinstance(member, property):
        returns = member.fget.__annotations__.get("return", "") if member.fget else ""
        return _described(f"- `{name}` → `{returns}` (property)", member)
    if isinstance(member, (staticmethod, classmethod)):
        return _described(f"- `{name}{_signature(member.__func__)}`", member.__func__)
    if callable(member):
        return _described(f"- `{name}{_signature(member)}`", member)
    return None


def _member_lines(klass: type) -> Iterator[str]:
    fields = {f.name: f for f in dataclasses.fields(klass)} if dataclasses.is_dataclass(klass) else {}
    for name in _member_names(klass):
        if name in fields:
            kind = getattr(fields[name].type, "__name__", fields[name].type)
            yield f"- `{name}: {kind}`"
            continue
        line = _member_line(inspect.getattr_static(klass, name, None), name)
        if line is not None:
            yield line


def render() -> str:
    out = [HEADER, _doc(hil.api), ""]
    for name in hil.api.__all__:
        obj = getattr(hil.api, name)
        out.append(f"## `{name}`\n")
        if isinstance(obj, type) and issubclass(obj, enum.Enum):
            out += [_doc(obj) or f"One of: {', '.join(m.value for m in obj)}.", ""]
            continue
        doc = _doc(obj)
        if isinstance(obj, type) and issubclass(obj, BaseException):
            out += [doc, ""]
            continue
        out += [doc, ""] if doc else []
        if isinstance(obj, type):
            lines = list(_member_lines(obj))
            out += lines + [""] if lines else []
    return "\n".join(out).rstrip() + "\n"


def main() -> int:
    sys.stdout.write(render())
    return 0


if __name__ == "__main__":
    sys.exit(main())
