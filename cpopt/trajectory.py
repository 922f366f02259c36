"""Deprecated: the old path of :mod:`cpopt.closedform.trajectory`, kept for one release.

Importing it warns and gives the new module itself, so its names (private ones included) and
monkeypatching behave as before.
"""

import importlib
import sys
import warnings

warnings.warn(
    "cpopt.trajectory moved to cpopt.closedform.trajectory (old path removed next release)",
    DeprecationWarning,
    stacklevel=2,
)
sys.modules[__name__] = importlib.import_module("cpopt.closedform.trajectory")
