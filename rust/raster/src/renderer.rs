//! One view's differentiable render, chaining the ops: project → rasterize → anti-alias, and back.
//!
//! [`Renderer`] owns every buffer, so that an optimization loop allocates nothing per iteration once
//! the sizes have settled.

use glam::{Vec2, Vec3};
use hairrecon_core::Camera;

use crate::antialias::{antialias_backward, antialias_forward, AaMethod, AaOutput};
use crate::error::RasterError;
use crate::image::Image;
use crate::rasterize::{attributes_backward, rasterize, Buffers};
use crate::screen::{RasterSettings, Screen, SegmentGrads, VertexGrads};

/// Differentiable renderer of segments for one view at a time.
#[derive(Debug, Clone)]
pub struct Renderer {
    pub screen: Screen,
    pub buffers: Buffers,
    pub aa: AaOutput,
    pub d_attrs: Image,
    pub seg_grads: SegmentGrads,
    pub vertex_grads: VertexGrads,
}

impl Renderer {
    pub fn new(method: AaMethod) -> Self {
        Self {
            screen: Screen::default(),
            buffers: Buffers::new(),
            aa: AaOutput::new(method),
            d_attrs: Image::default(),
            seg_grads: SegmentGrads::default(),
            vertex_grads: VertexGrads::default(),
        }
    }

    pub fn method(&self) -> AaMethod {
        self.aa.method
    }

    /// Renders 3D points seen by a camera; returns the anti-aliased attributes (see
    /// [`crate::channel`]).
    pub fn forward(
        &mut self,
        camera: &Camera,
        points: &[Vec3],
        segs: &[[u32; 2]],
        settings: RasterSettings,
    ) -> Result<&Image, RasterError> {
        self.screen.set_projected(camera, points, segs, settings)?;
        Ok(self.render())
    }

    /// Renders 2D pixel positions (depth 1); returns the anti-aliased attributes.
    pub fn forward_pixels(
        &mut self,
        width: u32,
        height: u32,
        pos: &[Vec2],
        segs: &[[u32; 2]],
        settings: RasterSettings,
    ) -> Result<&Image, RasterError> {
        self.screen.set_pixels(width, height, pos, None, segs, settings)?;
        Ok(self.render())
    }

    fn render(&mut self) -> &Image {
        rasterize(&self.screen, &mut self.buffers);
        antialias_forward(&self.screen, &self.buffers, &mut self.aa);
        &self.aa.image
    }

    /// Backward to per-vertex pixel (and half-width) gradients, given ∂L/∂(anti-aliased image).
    pub fn backward_screen(&mut self, d_image: &Image) -> Result<&VertexGrads, RasterError> {
        self.seg_grads.reset(self.screen.prims.len());
        antialias_backward(&self.screen, &self.buffers, &self.aa, d_image, &mut self.d_attrs, &mut self.seg_grads)?;
        attributes_backward(&self.screen, &self.buffers, &self.d_attrs, &mut self.seg_grads);
        self.screen.backward_vertices(&self.seg_grads, &mut self.vertex_grads);
        Ok(&self.vertex_grads)
    }

    /// Backward to 3D: adds ∂L/∂point into `out` (one entry per point of the last forward).
    pub fn backward(
        &mut self,
        camera: &Camera,
        points: &[Vec3],
        d_image: &Image,
        out: &mut [Vec3],
    ) -> Result<(), RasterError> {
        self.backward_screen(d_image)?;
        self.screen.backward_world(camera, points, &self.vertex_grads, out);
        Ok(())
    }
}
