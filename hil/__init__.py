"""hil: hardware-in-the-loop test harness for FATEK FBs PLCs."""

__version__ = "0.1.0"
