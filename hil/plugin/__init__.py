"""The pytest side: the plugin (options, fixtures, markers), its hooks, wire statistics and the reports."""
