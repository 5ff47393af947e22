"""What a status request tells, whatever the controller family."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class PlcStatus:
    """What a status request tells: RUN/STOP, flags, and (if the wire supports it) the PLC's identity."""

    running: bool | None
    flags: list[str] = field(default_factory=list)
    identity: dict[str, str] = field(default_factory=dict)
    via: str = ""

    def summary(self) -> str:
        state = {True: "RUN", False: "STOP", None: "RUN/STOP unknown"}[self.running]
        extra = [f for f in self.flags if f != "RUN"]
        return state + (f" ({', '.join(extra)})" if extra else "")
