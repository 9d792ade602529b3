"""The add-on's bpy-free core: camera maths, capture writing, surface attachment maths.

Nothing in this package imports ``bpy``; the Blender layer (``..scene_read``, ``..scene_build``,
``..operators``) extracts plain numbers and numpy arrays from the scene and hands them here, so this
code runs (and is tested) under plain Python.
"""
