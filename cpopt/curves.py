"""Deprecated: the old path of :mod:`cpopt.closedform.curves`, kept for one release.

Importing it warns and gives the new module itself, so its names (private ones included) and
monkeypatching behave as before.
"""

import importlib
import sys
import warnings

warnings.warn(
    "cpopt.curves moved to cpopt.closedform.curves (old path removed next release)",
    DeprecationWarning,
    stacklevel=2,
)
sys.modules[__name__] = importlib.import_module("cpopt.closedform.curves")
