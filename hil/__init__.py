"""hil: hardware-in-the-loop test harness for FATEK FBs PLCs.

PYTEST_DONT_REWRITE: ``hil run`` imports this package before pytest starts, so pytest could not rewrite the
asserts of its plugin modules anyway; saying so keeps every ``hil run`` from ending with that warning.
"""

__version__ = "0.1.0"
