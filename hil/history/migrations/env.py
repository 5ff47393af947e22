"""Alembic's environment: always on the connection :func:`hil.history.store.migrate` hands over (already in a
transaction and holding the store's migration lock), never from an ini file."""

from alembic import context

connection = context.config.attributes["connection"]
context.configure(connection=connection, transactional_ddl=True)
with context.begin_transaction():
    context.run_migrations()
