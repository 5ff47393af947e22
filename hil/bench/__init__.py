"""The bench: its profile (core sections + each family's), the base every family's bench shares."""
