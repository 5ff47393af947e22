"""Controller families, each a plug-in registered under the ``hil.families`` entry-point group."""
