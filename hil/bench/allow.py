"""The allow-list: what a test may write on this bench — the profile's ``[safety] writable`` elements — and what
the PLC rewrites itself (``volatile``: allowed, never journaled)."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from hil.core.errors import WriteRefused

SHOWN = 4  # refused elements named in the error, before "…"


@dataclass(frozen=True)
class AllowList:
    """The profile's ``[safety]`` as single elements (the guard's unit of permission)."""

    writable: frozenset[Any]
    volatile: frozenset[Any] = frozenset()

    def check(self, names: Iterable[Any], split: Callable[[Any], list[Any]]) -> list[Any]:
        """The elements a write to ``names`` covers (``split``: the family's address model); WriteRefused, naming
        the first few outside the list, unless every one is writable."""
        covered: list[Any] = []
        for name in names:
            parts = split(name)
            refused = [str(p) for p in parts if p not in self.writable]
            if refused:
                shown = ", ".join(refused[:SHOWN]) + ("…" if len(refused) > SHOWN else "")
                raise WriteRefused(
                    f"write to {name} refused: {shown} not in the bench's [safety] writable list — add the "
                    f"range to the profile if this test may change it on this bench")
            covered += parts
        return covered


__all__ = ["AllowList"]
