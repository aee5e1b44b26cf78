//! Numerical building blocks with no knowledge of the sensor: each piece of maths
//! exists once here and the layers above call it.

pub mod homography;
pub mod lm;
pub mod rng;
pub mod robust;
pub mod tls;
