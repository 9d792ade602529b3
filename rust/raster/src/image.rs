//! Multi-channel f32 images, row-major, channels interleaved.

use crate::error::RasterError;

/// A row-major image with `channels` interleaved f32 values per pixel.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub channels: usize,
    pub data: Vec<f32>,
}

impl Image {
    /// A zero image.
    pub fn zeros(width: u32, height: u32, channels: usize) -> Self {
        Self { width, height, channels, data: vec![0.0; width as usize * height as usize * channels] }
    }

    /// Resizes (reusing the allocation) and fills with zeros.
    pub fn reset(&mut self, width: u32, height: u32, channels: usize) {
        self.width = width;
        self.height = height;
        self.channels = channels;
        self.data.clear();
        self.data.resize(width as usize * height as usize * channels, 0.0);
    }

    pub fn num_pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The values of pixel `(x, y)`.
    pub fn pixel(&self, x: u32, y: u32) -> &[f32] {
        let i = (y as usize * self.width as usize + x as usize) * self.channels;
        &self.data[i..i + self.channels]
    }

    /// Channel `c` of pixel `(x, y)`.
    pub fn at(&self, x: u32, y: u32, c: usize) -> f32 {
        self.data[(y as usize * self.width as usize + x as usize) * self.channels + c]
    }

    /// One channel as its own single-channel image.
    pub fn channel(&self, c: usize) -> Image {
        let data = self.data.iter().skip(c).step_by(self.channels).copied().collect();
        Image { width: self.width, height: self.height, channels: 1, data }
    }

    /// Checks that `self` has the given shape.
    pub fn check_shape(&self, what: &'static str, width: u32, height: u32, channels: usize) -> Result<(), RasterError> {
        if self.width != width || self.height != height || self.channels != channels {
            return Err(RasterError::SizeMismatch {
                what,
                got_w: self.width,
                got_h: self.height,
                got_c: self.channels,
                want_w: width,
                want_h: height,
                want_c: channels,
            });
        }
        Ok(())
    }
}
