//! Circle-grid detection (to be written).
