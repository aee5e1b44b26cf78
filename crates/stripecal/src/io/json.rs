//! JSON helpers (io helper implements).
