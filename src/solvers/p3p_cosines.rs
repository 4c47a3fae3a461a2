//! stub
/// stub
pub fn p3p_cosines() {}
