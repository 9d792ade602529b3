"""The Blender extension's bpy-free core (``addon/hairrecon/core``), importable as ``hairrecon_addon_core``.

The extension's package is named ``hairrecon`` like the Rust module, so ``addon/`` cannot go on
``sys.path`` without hiding the module. Scripts and tests load the core under this other name instead,
which keeps one implementation of what they share with the extension: the Blender-to-OpenCV camera
conversion (``hairrecon_addon_core.camera``) and the sRGB curve (``hairrecon_addon_core.capture``).

    import addon_core
    camera = addon_core.load("camera")    # then: from hairrecon_addon_core.capture import ... works too
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path
from types import ModuleType
from typing import Optional

NAME = "hairrecon_addon_core"
CORE = Path(__file__).resolve().parent.parent / "addon" / "hairrecon" / "core"


def load(submodule: Optional[str] = None) -> ModuleType:
    """The core package (once per process), or its ``submodule`` (e.g. ``"camera"``)."""
    if NAME not in sys.modules:
        spec = importlib.util.spec_from_file_location(NAME, CORE / "__init__.py", submodule_search_locations=[str(CORE)])
        mod = importlib.util.module_from_spec(spec)
        sys.modules[NAME] = mod
        try:
            spec.loader.exec_module(mod)
        except BaseException:
            del sys.modules[NAME]
            raise
    return importlib.import_module(f"{NAME}.{submodule}") if submodule else sys.modules[NAME]
