"""Shared by the plotting scripts (plot_figures.py, plot_replay.py)."""
import math
import sys


def to_float(text):
    """float(text), NaN for an empty or non-numeric CSV field."""
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def import_pyplot(tool):
    """matplotlib.pyplot on the Agg backend, or None after saying on stderr what is missing."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as e:
        print("%s: matplotlib is missing (%s); install python3-matplotlib and run with "
              "/usr/bin/python3" % (tool, e), file=sys.stderr)
        return None
    return plt
