"""warp, imported with its messages on standard error rather than standard output.

warp writes its banner (``Warp 1.x initialized: ...``, the devices, the kernel cache) and
each kernel module's load time (``Module ... load on device 'cpu' took ...``) through its
logger, whose default writes them to standard output. loosefit's commands keep standard
output for what they produce (a table, JSON, a path) and say what they are doing on
standard error, so every loosefit module that uses warp imports it through
:func:`import_warp`, which installs a logger that writes those messages to standard error
before warp initialises. A logger a program installed itself (``warp.set_logger``) is
left as it is.
"""

from __future__ import annotations

import sys
import warnings
from types import ModuleType


class StderrLogger:
    """warp's logger (``warp.Logger``): debug and info messages, errors on standard error;
    warnings through :func:`warnings.warn`, as warp's own logger sends them."""

    def debug(self, message: str) -> None:
        sys.stderr.write(message + "\n")

    def info(self, message: str) -> None:
        sys.stderr.write(message + "\n")

    def warning(self, message: str, category=None, stacklevel: int = 1) -> None:
        warnings.warn(message, category, stacklevel=stacklevel + 1)

    def error(self, message: str) -> None:
        sys.stderr.write("Warp Error: " + message + "\n")


def import_warp() -> ModuleType:
    """The ``warp`` module, its messages routed to standard error (unless a program has
    installed a logger of its own). Call it before anything initialises warp (a kernel
    load, a device query, importing ``anny``)."""
    import warp

    logger = warp.get_logger()
    if type(logger).__module__.startswith("warp."):  # warp's default: standard output
        warp.set_logger(StderrLogger())
    return warp
