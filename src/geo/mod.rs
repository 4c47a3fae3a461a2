//! WGS84 geodetic ↔ ECEF ↔ local East-North-Up frames.
