"""Passwords out of everything hil shows: a URL (a history store's, a target's) and a command line that holds one.

A PostgreSQL URL carries its password in two places — the user part (``postgresql://hil:PASSWORD@db/x``) and the
query (``…/x?password=PASSWORD``) — and a password typed with a raw ``@`` (``hil:p@ss@db``) runs up to the *last*
``@`` before the host (a host has none), as :func:`urllib.parse.urlsplit` reads it.  SQLAlchemy's
``render_as_string(hide_password=True)`` masks neither of the last two (it shows ``?password=`` as given and
``hil:***@ss@db``), and importing it costs a run that only takes a lock; hence this one function, used wherever a
URL or a command line is shown or written down: the lock file, "in use by", the console, the reports, ``hil
history``.
"""

from __future__ import annotations

import re
from urllib.parse import parse_qsl, urlencode

#: what replaces a password
MASK = "***"
#: query parameters that carry a secret (libpq's and SQLAlchemy's spellings)
SECRET_KEYS = frozenset({"password", "passwd", "pwd", "sslpassword"})
# a URL in free text: scheme://… up to white space or a quote
_URL = re.compile(r"[A-Za-z][A-Za-z0-9+.-]*://[^\s'\"]+")


def hide_password(url: str) -> str:
    """``url`` with every password in it replaced by ``***`` (user part and query); the rest as given."""
    scheme, sep, rest = url.partition("://")
    if not sep:
        return url
    rest, hashmark, fragment = rest.partition("#")
    rest, question, query = rest.partition("?")
    if not rest.startswith("/"):  # an authority (not an SQLite path): a user part ends at its last '@'
        user, at, host = rest.rpartition("@")
        if at and ":" in user:
            rest = f"{user.partition(':')[0]}:{MASK}@{host}"
    if query:
        pairs = parse_qsl(query, keep_blank_values=True)
        if any(key.lower() in SECRET_KEYS for key, _ in pairs):
            query = urlencode([(key, MASK if key.lower() in SECRET_KEYS else value) for key, value in pairs],
                              safe="*/:@")
    return f"{scheme}{sep}{rest}{question}{query}{hashmark}{fragment}"


def hide_passwords(text: str) -> str:
    """``text`` (a command line, a message) with :func:`hide_password` applied to every URL in it."""
    return _URL.sub(lambda found: hide_password(found.group(0)), text)


__all__ = ["MASK", "hide_password", "hide_passwords"]
