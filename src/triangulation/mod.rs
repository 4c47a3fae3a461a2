//! Landmark positions from rays seen at several poses.
