"""The compiled module msid._msid, loaded on first use: the modules that call it import this one, so
the rest of the package (files, plots, regions) imports without it."""
from types import ModuleType
from typing import Optional

_MODULE: Optional[ModuleType] = None


def ext() -> ModuleType:
    """msid._msid, or ImportError saying how to build it."""
    global _MODULE
    if _MODULE is not None:
        return _MODULE
    try:
        from . import _msid
    except ImportError as e:
        raise ImportError(
            f"this needs msid's compiled extension msid._msid, which this msid package does not have ({e}); build "
            "it with the msid build (./bootstrap.sh build, then PYTHONPATH=build/python) or install the package "
            "with it: pip install ./tools/python (docs/python.md)") from None
    _MODULE = _msid
    return _msid
