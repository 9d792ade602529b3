//! A bounds-checked reader over a byte slice, shared by the binary readers.
//!
//! Every read checks that enough bytes are left and returns [`FormatErrorKind::Truncated`] otherwise;
//! [`Cursor::check_count`] rejects a count whose items cannot fit in the bytes left, so that readers
//! can reserve memory for a count only after it has been checked.

use super::{FormatError, FormatErrorKind, Result};

/// Byte order of binary data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Endian {
    Little,
    Big,
}

/// A position in a byte slice.
#[derive(Debug, Clone)]
pub struct Cursor<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    pub fn new(data: &'a [u8]) -> Self {
        Self { data, pos: 0 }
    }

    pub fn pos(&self) -> usize {
        self.pos
    }

    pub fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    /// Takes the next `n` bytes.
    pub fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        if n > self.remaining() {
            return Err(FormatErrorKind::Truncated {
                what: what.to_string(),
                offset: self.pos as u64,
                needed: n as u64,
                len: self.data.len() as u64,
            }
            .into());
        }
        let s = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        let s = self.take(N, what)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }

    pub fn u8(&mut self, what: &str) -> Result<u8> {
        Ok(self.array::<1>(what)?[0])
    }

    pub fn u16(&mut self, e: Endian, what: &str) -> Result<u16> {
        let a = self.array(what)?;
        Ok(match e {
            Endian::Little => u16::from_le_bytes(a),
            Endian::Big => u16::from_be_bytes(a),
        })
    }

    pub fn u32(&mut self, e: Endian, what: &str) -> Result<u32> {
        let a = self.array(what)?;
        Ok(match e {
            Endian::Little => u32::from_le_bytes(a),
            Endian::Big => u32::from_be_bytes(a),
        })
    }

    pub fn i32(&mut self, e: Endian, what: &str) -> Result<i32> {
        Ok(self.u32(e, what)? as i32)
    }

    pub fn f32(&mut self, e: Endian, what: &str) -> Result<f32> {
        Ok(f32::from_bits(self.u32(e, what)?))
    }

    pub fn f64(&mut self, e: Endian, what: &str) -> Result<f64> {
        let a = self.array(what)?;
        Ok(match e {
            Endian::Little => f64::from_le_bytes(a),
            Endian::Big => f64::from_be_bytes(a),
        })
    }

    /// Checks that `count` items of at least `min_size` bytes each fit in the bytes left, and returns
    /// the count as a `usize` that is then safe to reserve.
    pub fn check_count(&self, count: u64, min_size: u64, what: &'static str) -> Result<usize> {
        let available = self.remaining() as u64;
        match count.checked_mul(min_size) {
            Some(total) if total <= available => Ok(count as usize),
            _ => Err(FormatErrorKind::CountTooLarge { what, count, available, min_size }.into()),
        }
    }

    /// Fails if bytes are left after the last item.
    pub fn expect_end(&self, what: &'static str) -> Result<()> {
        match self.remaining() {
            0 => Ok(()),
            n => Err(FormatErrorKind::TrailingBytes { what, count: n as u64 }.into()),
        }
    }
}

/// A [`FormatErrorKind::NotFinite`] error.
pub fn not_finite(what: &'static str, index: usize, value: f64) -> FormatError {
    FormatErrorKind::NotFinite { what, index: index as u64, value }.into()
}
