"""Where the history goes: ``--hil-history URL|off``, else ``$HIL_HISTORY_URL``, else the bench profile's
``[history] url``, else SQLite in hil's state directory."""

from __future__ import annotations

import os
from pathlib import Path
from urllib.parse import quote, unquote

from hil.core.errors import InvalidValue
from hil.core.journal import state_dir

ENV = "HIL_HISTORY_URL"
OFF = "off"


def default_url() -> str:
    return sqlite_url(state_dir() / "history.sqlite")


def spool_url() -> str:
    """Where a run goes when its store cannot be reached (``hil history sync`` uploads it from there)."""
    return sqlite_url(state_dir() / "history-unsent.sqlite")


def sqlite_url(path: Path) -> str:
    return f"sqlite:///{Path(path).absolute()}"


def resolve(option: str | None = None, profile_url: str | None = None) -> str | None:
    """The store's URL, None when recording is off."""
    for given in (option, os.environ.get(ENV), profile_url):
        if given is None:
            continue
        given = given.strip()
        if not given:
            raise InvalidValue(f"the history URL is empty (--hil-history, ${ENV} or [history] url) — give a URL "
                               f"(sqlite:///PATH, postgresql://USER@HOST/DB) or 'off'")
        return None if given.lower() == OFF else normalise(given)
    return default_url()


def normalise(url: str) -> str:
    """``postgresql://`` through psycopg 3 (SQLAlchemy's own default is psycopg2, not a dependency); a bare path
    is an SQLite file."""
    if url.startswith(("postgresql://", "postgres://")):
        url = "postgresql+psycopg://" + url.split("://", 1)[1]
    if "://" not in url:
        return sqlite_url(Path(url).expanduser())
    return _quote_user_part(url)


def _quote_user_part(url: str) -> str:
    """A password typed with a raw '@' (``hil:p@ss@db``): its user part runs to the last '@' before the path (a host
    has none), quoted — so the driver reaches ``db`` with the whole password, instead of host ``ss@db`` (which its
    error message would then quote, password and all)."""
    scheme, sep, rest = url.partition("://")
    end = min((i for i in (rest.find("/"), rest.find("?")) if i >= 0), default=len(rest))
    authority = rest[:end]
    if authority.count("@") < 2:
        return url
    user, _, host = authority.rpartition("@")
    name, colon, password = user.partition(":")
    quoted = quote(unquote(name), safe="") + colon + quote(unquote(password), safe="")
    return f"{scheme}{sep}{quoted}@{host}{rest[end:]}"

