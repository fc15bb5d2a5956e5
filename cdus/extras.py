"""Which optional package a table helper needs, and the error that says how to get it.

pandas and xarray are the ``api`` extra (pyproject.toml): ``Trace.to_dataframe``,
``SweepTable.to_xarray`` and the like import them when called, never before, and without them
raise an ImportError naming the command that installs them.
"""

from __future__ import annotations

import importlib
from types import ModuleType

EXTRA = "api"  # the optional-dependency group with pandas and xarray
INSTALL = f"pip install -e '.[{EXTRA}]'"  # from the clone (README, "Python API")


def needs(module: str, what: str) -> ModuleType:
    """``module`` imported, or an ImportError: ``what`` needs it, and how to install it."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise ImportError(f"{what} needs {module}, an optional dependency of cdus: {INSTALL} in the clone "
                          f"(or pip install {module})") from None
