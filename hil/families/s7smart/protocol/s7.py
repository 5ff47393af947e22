"""What the S7 protocol is to the S7-200 SMART, for its client and its emulator's server alike: V memory is DB 1;
python-snap7 (an optional extra) carries it both ways."""

from __future__ import annotations

from typing import Any

from hil.core.errors import HilError

V_DB = 1  # V memory as S7 clients see it
DEFAULT_PORT = 102
INSTALL_HINT = "the S7 protocol needs python-snap7: pip install 'hil[s7]' (or pip install python-snap7)"


def snap7_module() -> Any:
    """python-snap7, or a HilError saying what to install."""
    try:
        import snap7
        import snap7.client
        import snap7.error
        import snap7.type
    except ImportError:
        raise HilError(INSTALL_HINT) from None
    return snap7
