"""Where the history goes: ``--hil-history URL|off``, else ``$HIL_HISTORY_URL``, else the bench profile's
``[history] url``, else SQLite in hil's state directory."""

from __future__ import annotations

import os
from pathlib import Path

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
            raise InvalidValue(f"the history URL is empty (--hil-history, ${ENV} or [history] url): give a URL "
                               f"(sqlite:///PATH, postgresql://USER@HOST/DB) or 'off'")
        return None if given.lower() == OFF else normalise(given)
    return default_url()


def normalise(url: str) -> str:
    """``postgresql://`` through psycopg 3 (SQLAlchemy's own default is psycopg2, not a dependency); a bare path
    is an SQLite file."""
    if url.startswith(("postgresql://", "postgres://")):
        return "postgresql+psycopg://" + url.split("://", 1)[1]
    if "://" not in url:
        return sqlite_url(Path(url).expanduser())
    return url


def shown(url: str) -> str:
    """The URL without its password, for messages and reports."""
    from sqlalchemy.engine import make_url
    try:
        return make_url(url).render_as_string(hide_password=True)
    except Exception:  # noqa: BLE001 - a URL SQLAlchemy cannot parse is shown as it was given, less any user part
        return url.split("@")[-1]
