"""The harness's exception tree: every failure names what was wrong and, where it can, what to do next."""

from __future__ import annotations


class HilError(Exception):
    """Base of every error the harness raises on purpose."""


class InvalidValue(HilError, ValueError):
    """A value refused before anything is sent: outside its range, not a valid date, not a known code or setting.
    (Also a ValueError, so code that checks values the standard way still catches it.)"""


class AddressError(HilError, ValueError):
    """An FBs element name that does not parse or lies outside the model's ranges."""


class UnreachableAddress(AddressError):
    """An address the chosen transport or map cannot reach (e.g. D4054 over the default Modbus map)."""

    def __init__(self, address: str, via: str, detail: str = "") -> None:
        self.address = address
        self.via = via
        msg = f"{address} cannot be reached over {via}"
        super().__init__(msg + (f": {detail}" if detail else ""))


class ProtocolError(HilError):
    """A frame that does not follow the protocol (checksum, station, command echo, length, format)."""


class PlcErrorReply(HilError):
    """The PLC answered with an error code instead of data."""

    def __init__(self, code: str, meaning: str, request: str = "", hint: str = "") -> None:
        self.code = code
        self.meaning = meaning
        self.request = request
        where = f" to {request}" if request else ""
        super().__init__(f"PLC replied error {code} ({meaning}){where}" + (f": {hint}" if hint else ""))


class TransportError(HilError):
    """The wire failed: cannot open, disconnected, or no usable reply."""


class ReplyTimeout(TransportError):
    """No complete reply within the timeout; the message says what was sent, to whom and how long we waited."""


class OutcomeUnknown(ReplyTimeout):
    """A write whose reply never came (or the line dropped after it was sent): it may or may not have been
    applied.  Writes are never repeated automatically — repeating one can be wrong (a counter preset)."""


class WriteRefused(HilError):
    """The safety guard refused a write before any byte was sent."""


class RestoreError(HilError):
    """The guard could not put the PLC back as it found it; lists what it could not restore."""

    def __init__(self, failures: list[tuple[str, int, str]]) -> None:
        self.failures = failures
        lines = "; ".join(f"{addr} (original {value}): {why}" for addr, value, why in failures)
        super().__init__(f"could not restore {len(failures)} address(es): {lines}")


class ProfileError(HilError):
    """A bench profile that is invalid; the message names the file and key."""


class TargetError(HilError, ValueError):
    """A target URL that cannot be understood; the message lists the forms that are."""


class EmulatorFault(HilError):
    """The emulator broke a rule every PLC keeps — a bug in one of its models, not a PLC's answer (a model changed a
    memory bank's size).  Raised by the scan, so the request served after it fails: a suite sees this error, never
    what the broken model left in memory."""



#: Where every error line starts, so a user (and a script) finds hil's complaint whatever printed it.
ERROR_PREFIX = "hil: error: "


def error_line(what: str, next_step: str = "") -> str:
    """The one form of every error line hil prints: ``hil: error: <what was wrong> — <what to do next>``, on one
    line.  ``what`` may already say what to do (hil's messages mostly do); ``next_step`` is added where the caller
    knows it separately (argparse's messages do not: "see hil run --help", "did you mean …")."""
    text = " ".join(what.split()).removeprefix(ERROR_PREFIX).removeprefix("hil: ")
    step = " ".join(next_step.split())
    return ERROR_PREFIX + text + (f" — {step}" if step else "")
