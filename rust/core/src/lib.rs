//! hairrecon-core: the types that every stage of hairrecon shares.
//!
//! - [`capture`]: capture folders (capture.json + images, masks, meshes), validated on load.
//! - [`camera`]: OpenCV pinhole cameras (K, R, t) with projection and its Jacobian.
//! - [`strands`]: strand sets stored flat (points + per-strand counts, root first).
//! - [`mesh`]: triangle meshes, PLY/OBJ I/O, and a BVH for ray casts and closest points.
//! - [`image_io`]: PNG (8/16-bit) and OpenEXR float images.
//! - [`formats`]: mesh PLY/OBJ and hair files: Yuksel `.hair`, USC-HairSalon `.data`, PLY polylines, OBJ lines.
//! - [`metric`]: the strand precision/recall/F1 metric (points matched at a distance and an angle).
//! - [`layer_height`]: how far the hair stands off the scalp over the crown, against the ground truth's.
//! - [`spatial`]: the one kd-tree index over oriented points and the one arc-length sampler.
//!
//! Everything is validated at construction: inner loops assume finite, consistent data.

pub mod camera;
pub mod capture;
pub mod capture_frame;
pub mod formats;
pub mod image_io;
pub mod layer_height;
pub mod mesh;
pub mod metric;
pub mod scalp;
pub mod similarity;
pub mod spatial;
pub mod strands;

pub use camera::{Camera, CameraError};
pub use mesh::{Bvh, MeshError, TriMesh};
pub use strands::{StrandError, StrandSet};

pub use formats::{read_mesh, read_strands, write_mesh, write_strands, FormatError, FormatErrorKind};
pub use image_io::{GrayImage32, RgbImage32};
