"""The family-neutral core: errors, link lifecycle, time base, the bench lock, where the project's files are.

Imports nothing else of hil; every other layer may import it.
"""
