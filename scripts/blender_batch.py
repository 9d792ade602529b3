"""What the batch scripts run under Blender share (``reconstruct.py``, ``physics_check.py``, ``demo.py``):
their arguments after ``--``, their one kind of failure, and the hairrecon extension made available to
``bpy.ops``."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def script_args() -> list[str]:
    argv = sys.argv
    if "--" in argv:
        return argv[argv.index("--") + 1:]
    return argv[1:]


class Failure(Exception):
    pass


def ensure_addon(bpy):
    """Makes bpy.ops.hairrecon available: an enabled or installed extension, else the source tree."""
    if hasattr(bpy.types, "HAIRRECON_OT_reconstruct"):
        return bpy.types.HAIRRECON_OT_reconstruct.__module__.rsplit(".", 1)[0]
    import addon_utils

    for mod in addon_utils.modules(refresh=True):
        if mod.__name__.startswith("bl_ext.") and mod.__name__.endswith(".hairrecon"):
            addon_utils.enable(mod.__name__, default_set=False, handle_error=None)
            if hasattr(bpy.types, "HAIRRECON_OT_reconstruct"):
                return mod.__name__
    return register_source_addon()


def register_source_addon() -> str:
    """Registers ``addon/hairrecon`` from this source tree under the name ``hairrecon_addon`` (which does not
    hide the ``hairrecon`` library module) and returns that name."""
    pkg = ROOT / "addon" / "hairrecon"
    spec = importlib.util.spec_from_file_location("hairrecon_addon", pkg / "__init__.py", submodule_search_locations=[str(pkg)])
    mod = importlib.util.module_from_spec(spec)
    sys.modules["hairrecon_addon"] = mod
    spec.loader.exec_module(mod)
    mod.register()
    return "hairrecon_addon"
