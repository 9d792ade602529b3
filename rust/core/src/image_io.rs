//! Image I/O: PNG (8/16-bit) and OpenEXR float.
