"""scipy's compiled routines, loaded from their own files.

A scipy subpackage costs far more to import than the loop inside it that we call:
``scipy.signal`` about 1.4 s of CPU for one second-order filter loop, ``scipy.fft`` about
0.2 s (it pulls in ``scipy.special`` and scipy's array-API layer) for pocketfft's real
transforms. Every render process, pool worker and DataLoader worker pays its imports, so
the renderers load just the compiled module, found beside the package it belongs to
without running that package's ``__init__``. The module is registered under its own name:
a later ``import scipy.fft`` (or ``scipy.signal``) finds it there and does not load it
twice. Where scipy keeps its files elsewhere, callers fall back to the public function:
the same numbers, only a slower start.
"""
from __future__ import annotations

import importlib.machinery
import importlib.util
import os
import sys
from functools import lru_cache


@lru_cache(maxsize=None)
def scipy_extension(dotted: str):
    """The compiled module ``scipy.<dotted>`` (e.g. ``"fft._pocketfft.pypocketfft"``),
    or None when its file is not where this scipy keeps it."""
    name = f"scipy.{dotted}"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.find_spec("scipy")  # finds the package without importing it
    if spec is None or not spec.submodule_search_locations:
        return None
    base = os.path.join(spec.submodule_search_locations[0], *dotted.split("."))
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        if os.path.isfile(base + suffix):
            try:
                mod_spec = importlib.util.spec_from_file_location(name, base + suffix)
                module = importlib.util.module_from_spec(mod_spec)
                mod_spec.loader.exec_module(module)
            except ImportError:
                return None
            sys.modules[name] = module
            return module
    return None
