"""Finds the `photonlm` bridge package.

During development the package is on sys.path (python_bridge/). In the
installed add-on zip it lives at photonlm_blender/lib/photonlm/ with the native
library beside it. The import is lazy so that the add-on registers even when
the native library is missing; the error then appears when a bake starts and
in the panel.
"""
import os
import sys

_module = None
_error = None


def get():
    """The imported `photonlm` module. Raises RuntimeError with a readable message if unavailable."""
    global _module, _error
    if _module is not None:
        return _module
    try:
        try:
            import photonlm
        except ImportError:
            lib_dir = os.path.join(os.path.dirname(os.path.abspath(__file__)), "lib")
            if lib_dir not in sys.path:
                sys.path.insert(0, lib_dir)
            import photonlm
    except Exception as e:  # ImportError, or the bridge's LibraryNotFoundError (an OSError)
        _error = "PhotonLM engine not available: %s" % e
        raise RuntimeError(_error) from e
    _module = photonlm
    _error = None
    return _module


def error():
    """Why the bridge could not be loaded, or None (also None before the first attempt)."""
    return _error


def engine_defaults():
    """The engine's default bake settings by the names of photonlm.Scene.bake's arguments (the one
    place they are defined, plm_bake_settings_default); {} when the engine cannot be loaded."""
    try:
        return get().default_settings()
    except RuntimeError:
        return {}


def available():
    try:
        get()
        return True
    except RuntimeError:
        return False
