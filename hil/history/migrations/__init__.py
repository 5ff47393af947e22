"""Alembic revisions of the store's schema (``versions/``), run by :func:`hil.history.store.migrate`."""
