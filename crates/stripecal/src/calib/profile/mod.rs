//! A calibrated line profiler's calibration from profiles of a reference sphere
//! (spec/DATASET.md, "A profile dataset"): each profile's arc of the sphere ([`arc`]),
//! the closed-form start of `T_hand_sensor` and the sphere's centre ([`start`]); the
//! one-stage adjustment over every profile point is [`crate::calib::joint::profile`].

pub mod arc;
pub mod start;
