//! File formats: meshes (PLY, OBJ) and hair strands (`.hair`, `.data`, PLY polylines, OBJ lines).
