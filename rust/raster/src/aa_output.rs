//! What the three anti-aliasing methods share: the method's name, the output with its saved
//! buffer ([`AaOutput`]), the neighbourhood, and the scatter of corner gradients. The dispatch over
//! methods is the `antialias` module's.

use glam::Vec2;

use crate::image::Image;
use crate::screen::SegmentGrads;

/// The anti-aliasing method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AaMethod {
    Ours,
    Nvdiffrast,
    Splat,
}

impl AaMethod {
    pub const ALL: [AaMethod; 3] = [AaMethod::Ours, AaMethod::Nvdiffrast, AaMethod::Splat];

    pub fn name(self) -> &'static str {
        match self {
            AaMethod::Ours => "ours",
            AaMethod::Nvdiffrast => "nvdiffrast",
            AaMethod::Splat => "splat",
        }
    }

    /// Parses `ours`, `nvdiffrast` or `splat`.
    pub fn parse(s: &str) -> Option<Self> {
        AaMethod::ALL.into_iter().find(|m| m.name() == s)
    }
}

/// The anti-aliased image and what the backward pass needs, reused between calls.
#[derive(Debug, Clone)]
pub struct AaOutput {
    pub method: AaMethod,
    /// The anti-aliased attributes, same shape as the input attributes.
    pub image: Image,
    /// Per pixel and neighbour slot: the chosen edge (method-specific code, `u32::MAX` for none).
    pub(crate) edges: Vec<u32>,
    /// Per pixel and neighbour slot: the edge distance or crossing parameter.
    pub(crate) vals: Vec<f32>,
}

impl AaOutput {
    pub fn new(method: AaMethod) -> Self {
        Self { method, image: Image::default(), edges: Vec::new(), vals: Vec::new() }
    }

    /// The saved edge choices (one code per pixel and neighbour slot; `u32::MAX` for none). Two
    /// renders with equal ids and equal edge choices are joined by a smooth path of the AA output,
    /// which is what a finite-difference check needs.
    pub fn saved_edges(&self) -> &[u32] {
        &self.edges
    }
}

pub(crate) const NONE: u32 = u32::MAX;

/// The 8-neighbourhood, in an order where slot `7 − k` is the opposite of slot `k`.
pub(crate) const N8: [(i32, i32); 8] = [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)];

/// Adds a list of per-band corner gradients `(prim·4 + corner, gradient)` into `grads`.
pub(crate) fn scatter_corners(parts: Vec<Vec<(u32, Vec2)>>, grads: &mut SegmentGrads) {
    for part in parts {
        for (code, g) in part {
            grads.add_corner(code, g);
        }
    }
}
