"""Disturbance and state observers, one module each, behind one interface (:mod:`.base`).

Importing this package imports every module in it, so each observer's ``@register_observer``
runs and :func:`make_observer` knows all of them.
"""

import importlib
import pkgutil

from .base import Observer, ObserverEstimate, make_observer, observer_names, register_observer

for _info in pkgutil.iter_modules(__path__):
    if not _info.name.startswith("_"):
        importlib.import_module(f"{__name__}.{_info.name}")

__all__ = ["Observer", "ObserverEstimate", "make_observer", "observer_names", "register_observer"]
