//! hairrecon-raster.
