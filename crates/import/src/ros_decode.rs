//! Decoding (only) of the few ROS 2 messages a drive needs, from their CDR serialization as
//! rosbag2 stores it in MCAP (`message_encoding = "cdr"`).
//!
//! A serialized message starts with a 4-byte encapsulation header: bytes 0–1 the
//! representation identifier (`0x0000` CDR big-endian, `0x0001` CDR little-endian,
//! `0x0006`/`0x0007` plain CDR2 big/little-endian), bytes 2–3 options (ignored). Primitives are
//! aligned to their size (at most 4 in CDR2) counted from the end of that header; a string is
//! a `u32` length that includes the terminating NUL, then the bytes; a sequence is a `u32`
//! count then the elements. The messages read are `sensor_msgs/msg/CompressedImage`,
//! `sensor_msgs/msg/Image`, `sensor_msgs/msg/NavSatFix` and `sensor_msgs/msg/Imu`
//! (their definitions are those of ROS 2 Humble to Rolling).
//!
//! # Limits
//! Strings are at most [`MAX_STRING_BYTES`] bytes and byte sequences at most
//! [`MAX_DATA_BYTES`]; nothing is allocated before its length is checked against the bytes
//! that remain. A decoder never panics on input; it returns a [`CdrError`] naming the field.

/// Longest accepted string (frame ids, image formats and encodings), bytes.
pub const MAX_STRING_BYTES: usize = 4096;
/// Largest accepted byte sequence (an image's data), bytes: 256 MiB.
pub const MAX_DATA_BYTES: usize = 256 << 20;
/// Size of the encapsulation header.
const HEADER_LEN: usize = 4;

/// Why a message could not be decoded.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// The message is shorter than its encapsulation header.
    #[error("message of {0} bytes has no CDR encapsulation header")]
    NoHeader(usize),
    /// The representation identifier is not plain CDR or CDR2.
    #[error("unsupported CDR representation 0x{0:04x} (only plain CDR/CDR2, big or little endian)")]
    Representation(u16),
    /// The message ends inside a field.
    #[error("field `{field}`: message ends at byte {at} (needs {need} more)")]
    Truncated {
        /// The field being read.
        field: &'static str,
        /// Offset in the message.
        at: usize,
        /// Bytes missing.
        need: usize,
    },
    /// A length is larger than the limit.
    #[error("field `{field}`: length {len} exceeds the limit {limit}")]
    TooLong {
        /// The field.
        field: &'static str,
        /// The length given.
        len: u64,
        /// The limit.
        limit: usize,
    },
    /// A string is not NUL-terminated UTF-8.
    #[error("field `{0}`: not a NUL-terminated UTF-8 string")]
    BadString(&'static str),
}

/// A reader over one CDR-serialized message.
#[derive(Debug)]
pub struct CdrReader<'a> {
    data: &'a [u8],
    pos: usize,
    little: bool,
    max_align: usize,
}

impl<'a> CdrReader<'a> {
    /// Starts reading `data` (encapsulation header included).
    ///
    /// # Errors
    /// [`CdrError::NoHeader`], [`CdrError::Representation`].
    pub fn new(data: &'a [u8]) -> Result<Self, CdrError> {
        if data.len() < HEADER_LEN {
            return Err(CdrError::NoHeader(data.len()));
        }
        let id = u16::from_be_bytes([data[0], data[1]]);
        let (little, max_align) = match id {
            0x0000 => (false, 8),
            0x0001 => (true, 8),
            0x0006 => (false, 4),
            0x0007 => (true, 4),
            other => return Err(CdrError::Representation(other)),
        };
        Ok(Self {
            data,
            pos: HEADER_LEN,
            little,
            max_align,
        })
    }

    /// Whether the message is little-endian.
    pub fn is_little_endian(&self) -> bool {
        self.little
    }

    fn take(&mut self, n: usize, align: usize, field: &'static str) -> Result<&'a [u8], CdrError> {
        let align = align.min(self.max_align).max(1);
        let rel = self.pos - HEADER_LEN;
        let pad = (align - rel % align) % align;
        let start = self.pos + pad;
        let end = start.checked_add(n).filter(|&e| e <= self.data.len());
        let Some(end) = end else {
            return Err(CdrError::Truncated {
                field,
                at: self.pos,
                need: (start + n).saturating_sub(self.data.len()),
            });
        };
        self.pos = end;
        Ok(&self.data[start..end])
    }

    fn array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], CdrError> {
        let bytes = self.take(N, N, field)?;
        let mut out = [0u8; N];
        out.copy_from_slice(bytes);
        if !self.little {
            out.reverse();
        }
        Ok(out)
    }

    /// An `uint8`.
    pub fn u8(&mut self, field: &'static str) -> Result<u8, CdrError> {
        Ok(self.take(1, 1, field)?[0])
    }

    /// An `int8`.
    pub fn i8(&mut self, field: &'static str) -> Result<i8, CdrError> {
        Ok(i8::from_le_bytes([self.u8(field)?]))
    }

    /// An `uint16`.
    pub fn u16(&mut self, field: &'static str) -> Result<u16, CdrError> {
        Ok(u16::from_le_bytes(self.array(field)?))
    }

    /// An `uint32`.
    pub fn u32(&mut self, field: &'static str) -> Result<u32, CdrError> {
        Ok(u32::from_le_bytes(self.array(field)?))
    }

    /// An `int32`.
    pub fn i32(&mut self, field: &'static str) -> Result<i32, CdrError> {
        Ok(i32::from_le_bytes(self.array(field)?))
    }

    /// A `float64`.
    pub fn f64(&mut self, field: &'static str) -> Result<f64, CdrError> {
        Ok(f64::from_le_bytes(self.array(field)?))
    }

    /// A `float64[N]`.
    pub fn f64_array<const N: usize>(&mut self, field: &'static str) -> Result<[f64; N], CdrError> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64(field)?;
        }
        Ok(out)
    }

    /// A `string` (at most [`MAX_STRING_BYTES`]).
    pub fn string(&mut self, field: &'static str) -> Result<&'a str, CdrError> {
        let len = self.u32(field)? as usize;
        if len > MAX_STRING_BYTES {
            return Err(CdrError::TooLong {
                field,
                len: len as u64,
                limit: MAX_STRING_BYTES,
            });
        }
        if len == 0 {
            // Some writers send an empty string as length 0 without the NUL.
            return Ok("");
        }
        let bytes = self.take(len, 1, field)?;
        let (last, text) = bytes.split_last().ok_or(CdrError::BadString(field))?;
        if *last != 0 {
            return Err(CdrError::BadString(field));
        }
        std::str::from_utf8(text).map_err(|_| CdrError::BadString(field))
    }

    /// A `uint8[]` sequence (at most [`MAX_DATA_BYTES`]), borrowed.
    pub fn bytes(&mut self, field: &'static str) -> Result<&'a [u8], CdrError> {
        let len = self.u32(field)? as usize;
        if len > MAX_DATA_BYTES {
            return Err(CdrError::TooLong {
                field,
                len: len as u64,
                limit: MAX_DATA_BYTES,
            });
        }
        self.take(len, 1, field)
    }
}

/// `std_msgs/msg/Header`: the stamp and the frame id.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// Stamp seconds (`builtin_interfaces/Time.sec`).
    pub sec: i32,
    /// Stamp nanoseconds.
    pub nanosec: u32,
    /// The coordinate frame id.
    pub frame_id: String,
}

impl Header {
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            sec: r.i32("header.stamp.sec")?,
            nanosec: r.u32("header.stamp.nanosec")?,
            frame_id: r.string("header.frame_id")?.to_string(),
        })
    }

    /// The stamp in nanoseconds since the Unix epoch (negative before 1970).
    pub fn stamp_ns(&self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
}

/// `sensor_msgs/msg/CompressedImage` (the data borrowed).
#[derive(Clone, Debug, PartialEq)]
pub struct CompressedImage<'a> {
    /// The header.
    pub header: Header,
    /// The format (`jpeg`, `png`, `rgb8; jpeg compressed bgr8`, …).
    pub format: &'a str,
    /// The encoded image.
    pub data: &'a [u8],
}

/// Decodes a `sensor_msgs/msg/CompressedImage`.
///
/// # Errors
/// [`CdrError`] naming the field.
pub fn compressed_image(data: &[u8]) -> Result<CompressedImage<'_>, CdrError> {
    let mut r = CdrReader::new(data)?;
    Ok(CompressedImage {
        header: Header::read(&mut r)?,
        format: r.string("format")?,
        data: r.bytes("data")?,
    })
}

/// `sensor_msgs/msg/Image` (the data borrowed).
#[derive(Clone, Debug, PartialEq)]
pub struct RawImage<'a> {
    /// The header.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding (`mono8`, `rgb8`, `bgr8`, `mono16`, …).
    pub encoding: &'a str,
    /// Whether multi-byte pixels are big-endian.
    pub is_bigendian: bool,
    /// Bytes per row.
    pub step: u32,
    /// The pixels, row after row.
    pub data: &'a [u8],
}

/// Decodes a `sensor_msgs/msg/Image`.
///
/// # Errors
/// [`CdrError`] naming the field.
pub fn raw_image(data: &[u8]) -> Result<RawImage<'_>, CdrError> {
    let mut r = CdrReader::new(data)?;
    Ok(RawImage {
        header: Header::read(&mut r)?,
        height: r.u32("height")?,
        width: r.u32("width")?,
        encoding: r.string("encoding")?,
        is_bigendian: r.u8("is_bigendian")? != 0,
        step: r.u32("step")?,
        data: r.bytes("data")?,
    })
}

/// `sensor_msgs/msg/NavSatFix`.
#[derive(Clone, Debug, PartialEq)]
pub struct NavSatFix {
    /// The header (the stamp is the fix time).
    pub header: Header,
    /// `status.status`: −1 no fix, 0 fix, 1 SBAS, 2 GBAS.
    pub status: i8,
    /// `status.service` bit mask (1 GPS, 2 GLONASS, 4 COMPASS, 8 GALILEO).
    pub service: u16,
    /// Latitude, degrees.
    pub latitude: f64,
    /// Longitude, degrees.
    pub longitude: f64,
    /// Altitude above the WGS84 ellipsoid, metres.
    pub altitude: f64,
    /// Position covariance, m², ENU, row-major.
    pub position_covariance: [f64; 9],
    /// 0 unknown, 1 approximated, 2 diagonal known, 3 known.
    pub position_covariance_type: u8,
}

/// Decodes a `sensor_msgs/msg/NavSatFix`.
///
/// # Errors
/// [`CdrError`] naming the field.
pub fn nav_sat_fix(data: &[u8]) -> Result<NavSatFix, CdrError> {
    let mut r = CdrReader::new(data)?;
    Ok(NavSatFix {
        header: Header::read(&mut r)?,
        status: r.i8("status.status")?,
        service: r.u16("status.service")?,
        latitude: r.f64("latitude")?,
        longitude: r.f64("longitude")?,
        altitude: r.f64("altitude")?,
        position_covariance: r.f64_array("position_covariance")?,
        position_covariance_type: r.u8("position_covariance_type")?,
    })
}

/// `sensor_msgs/msg/Imu`.
#[derive(Clone, Debug, PartialEq)]
pub struct Imu {
    /// The header.
    pub header: Header,
    /// Orientation quaternion `(x, y, z, w)`.
    pub orientation: [f64; 4],
    /// Its covariance (rad², row-major; element 0 = −1: no orientation).
    pub orientation_covariance: [f64; 9],
    /// Angular velocity, rad/s.
    pub angular_velocity: [f64; 3],
    /// Its covariance.
    pub angular_velocity_covariance: [f64; 9],
    /// Linear acceleration, m/s².
    pub linear_acceleration: [f64; 3],
    /// Its covariance.
    pub linear_acceleration_covariance: [f64; 9],
}

/// Decodes a `sensor_msgs/msg/Imu`.
///
/// # Errors
/// [`CdrError`] naming the field.
pub fn imu(data: &[u8]) -> Result<Imu, CdrError> {
    let mut r = CdrReader::new(data)?;
    Ok(Imu {
        header: Header::read(&mut r)?,
        orientation: r.f64_array("orientation")?,
        orientation_covariance: r.f64_array("orientation_covariance")?,
        angular_velocity: r.f64_array("angular_velocity")?,
        angular_velocity_covariance: r.f64_array("angular_velocity_covariance")?,
        linear_acceleration: r.f64_array("linear_acceleration")?,
        linear_acceleration_covariance: r.f64_array("linear_acceleration_covariance")?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tiny CDR writer for the tests (both endiannesses).
    struct W {
        out: Vec<u8>,
        little: bool,
    }
    impl W {
        fn new(little: bool) -> Self {
            Self {
                out: vec![0, u8::from(little), 0, 0],
                little,
            }
        }
        fn align(&mut self, n: usize) {
            while !(self.out.len() - 4).is_multiple_of(n) {
                self.out.push(0);
            }
        }
        fn put(&mut self, mut b: Vec<u8>) {
            self.align(b.len());
            if !self.little {
                b.reverse();
            }
            self.out.extend(b);
        }
        fn string(&mut self, s: &str) {
            self.put(((s.len() + 1) as u32).to_le_bytes().to_vec());
            self.out.extend(s.as_bytes());
            self.out.push(0);
        }
    }

    fn nav(little: bool) -> Vec<u8> {
        let mut w = W::new(little);
        w.put(1_700_000_000i32.to_le_bytes().to_vec());
        w.put(250_000_000u32.to_le_bytes().to_vec());
        w.string("gps");
        w.out.push(0xff); // status -1
        w.put(1u16.to_le_bytes().to_vec());
        for v in [37.5, -122.25, 12.5] {
            w.put(f64::to_le_bytes(v).to_vec());
        }
        for k in 0..9 {
            w.put(f64::to_le_bytes(k as f64).to_vec());
        }
        w.out.push(2);
        w.out
    }

    #[test]
    fn navsatfix_both_endiannesses() {
        for little in [true, false] {
            let m = nav_sat_fix(&nav(little)).unwrap();
            assert_eq!(m.header.stamp_ns(), 1_700_000_000_250_000_000);
            assert_eq!(m.header.frame_id, "gps");
            assert_eq!((m.status, m.service), (-1, 1));
            assert_eq!((m.latitude, m.longitude, m.altitude), (37.5, -122.25, 12.5));
            assert_eq!(m.position_covariance[8], 8.0);
            assert_eq!(m.position_covariance_type, 2);
        }
    }

    #[test]
    fn truncations_and_bad_headers_are_errors() {
        let full = nav(true);
        for n in 0..full.len() {
            assert!(nav_sat_fix(&full[..n]).is_err(), "prefix {n}");
        }
        let mut pl = full.clone();
        pl[1] = 3; // PL_CDR_LE
        assert_eq!(nav_sat_fix(&pl), Err(CdrError::Representation(3)));
        let mut big = vec![0, 1, 0, 0];
        big.extend(0i32.to_le_bytes());
        big.extend(0u32.to_le_bytes());
        big.extend(u32::MAX.to_le_bytes());
        assert!(matches!(
            compressed_image(&big),
            Err(CdrError::TooLong {
                field: "header.frame_id",
                ..
            })
        ));
    }

    #[test]
    fn compressed_image_borrows_its_data() {
        let mut w = W::new(true);
        w.put(5i32.to_le_bytes().to_vec());
        w.put(6u32.to_le_bytes().to_vec());
        w.string("cam0");
        w.string("png");
        w.put(3u32.to_le_bytes().to_vec());
        w.out.extend([1, 2, 3]);
        let m = compressed_image(&w.out).unwrap();
        assert_eq!((m.format, m.data), ("png", &[1u8, 2, 3][..]));
        assert_eq!(m.header.stamp_ns(), 5_000_000_006);
    }
}
