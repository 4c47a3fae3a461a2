//! OMG CDR (XCDR1, little-endian) encoding of ROS 2 messages, as `rmw` serializes them:
//! a 4-byte encapsulation header `00 01 00 00` (CDR_LE), then every field in order,
//! each primitive aligned to its own size counted from the end of the header; a string is
//! a `u32` length that counts its terminating NUL, the bytes and the NUL; a fixed-size
//! array is its elements without a length.
//!
//! # References
//! OMG, *DDS-XTypes* 1.3, §7.4.3 (XCDR1 "PLAIN_CDR" encoding); the ROS 2 type mapping in
//! `rosidl_typesupport_fastrtps`.

/// The encapsulation header of a little-endian CDR payload.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// A CDR little-endian writer.
#[derive(Clone, Debug)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    /// A payload with its encapsulation header and no field yet.
    pub fn new() -> Self {
        Self {
            buf: CDR_LE_HEADER.to_vec(),
        }
    }

    /// Pads to a multiple of `n` bytes after the header.
    fn align(&mut self, n: usize) {
        let offset = self.buf.len() - CDR_LE_HEADER.len();
        let pad = (n - offset % n) % n;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    /// An `int8`.
    pub fn i8(&mut self, v: i8) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `uint8`.
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// A `uint16`.
    pub fn u16(&mut self, v: u16) {
        self.align(2);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A fixed-size `float64[N]`.
    pub fn f64_array(&mut self, values: &[f64]) {
        for &v in values {
            self.f64(v);
        }
    }

    /// A `string` (UTF-8; a NUL inside is written as it is, which ROS would not send).
    pub fn string(&mut self, s: &str) {
        let len = u32::try_from(s.len() + 1).unwrap_or(u32::MAX);
        self.u32(len);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// The payload.
    pub fn into_bytes(self) -> Vec<u8> {
        self.buf
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_counts_from_the_end_of_the_header() {
        // std_msgs/Header { stamp { sec 1, nanosec 2 }, frame_id "map" } then a float64:
        // 4 + 4 + (4 + "map\0") = 16 bytes, already 8-aligned.
        let mut w = CdrWriter::new();
        w.i32(1);
        w.u32(2);
        w.string("map");
        w.f64(1.5);
        let b = w.into_bytes();
        assert_eq!(&b[..4], &CDR_LE_HEADER);
        assert_eq!(&b[4..8], &1i32.to_le_bytes());
        assert_eq!(&b[12..16], &4u32.to_le_bytes());
        assert_eq!(&b[16..20], b"map\0");
        assert_eq!(&b[20..28], &1.5f64.to_le_bytes());
        // A 2-character frame id ends at offset 15 after the header: an int8 fits there,
        // a uint16 is aligned to 16 and a float64 to 24.
        let mut w = CdrWriter::new();
        w.i32(1);
        w.u32(2);
        w.string("ab");
        w.i8(-1);
        w.u16(7);
        w.f64(2.0);
        let b = w.into_bytes();
        assert_eq!(b[4 + 15], 0xff);
        assert_eq!(&b[4 + 16..4 + 18], &7u16.to_le_bytes());
        assert_eq!(&b[4 + 24..4 + 32], &2.0f64.to_le_bytes());
        assert_eq!(b.len(), 4 + 32);
    }
}
