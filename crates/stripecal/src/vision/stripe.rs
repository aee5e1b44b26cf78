//! Laser stripe extraction (to be written).
