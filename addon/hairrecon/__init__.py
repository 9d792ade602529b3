"""hairrecon for Blender: reconstruct hair strands from calibrated photos of a head.

An extension (Blender 4.2+). The reconstruction itself is the Rust library ``hairrecon``, bundled
as an abi3 wheel (see blender_manifest.toml); this package holds the Blender side:

- ``core/``: bpy-free camera maths, capture writing and surface attachment (unit-testable),
- ``scene_read`` / ``scene_build``: scene -> numpy, numpy -> Curves/meshes/cameras,
- ``session``: one run (capture, job, result), ``operators``, ``props``, ``ui``,
- ``import_calibration``: File > Import of COLMAP, Metashape and transforms.json calibrations,
- ``fit_head``: Fit Head, the bundled head and scalp fitted to the raw mesh,
- ``physics``: Test Hair Physics, Blender's hair dynamics on the result, measured.
"""

from . import fit_head, import_calibration, operators, physics, props, ui

_MODULES = (props, operators, fit_head, import_calibration, physics, ui)


def register():
    for m in _MODULES:
        m.register()


def unregister():
    for m in reversed(_MODULES):
        m.unregister()
