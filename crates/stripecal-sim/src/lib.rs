//! # stripecal-sim — the digital twin
//!
//! Renders calibration datasets and ball scans of a robot-carried laser-stripe sensor
//! with known truth, in the files of spec/DATASET.md, as the test bed of stripecal and
//! the data behind `stripecal demo`.
//!
//! ## What is modelled
//!
//! - Geometry: the true camera (pinhole + distortion), the true robot (nominal DH plus
//!   optional errors), hand-eye X, robot-world Z, a target of any kind of the contract
//!   (`board.kind`: a circle grid with markers, an asymmetric circle grid, a chessboard;
//!   [`target`]) printed on a plate lying on a table, a sphere on the table, a laser
//!   sheet with Gaussian thickness.
//! - Rendering ([`render`]): ray casting from every pixel with >= 4 x 4 supersampling
//!   (4x finer on edge pixels, 8x at a chessboard's square corners) through the exact
//!   inverse distortion.
//! - Image formation ([`imaging`]): ambient x reflectance, vignetting, laser radiance
//!   with incidence, fall-off and shadows, speckle, Gaussian PSF, photon and read
//!   noise, clipping, 8/16-bit quantisation.
//! - Truth ([`truth`]): imaged target points per image (circle centres as outline
//!   centroids, chessboard corners as projected points) and stripe centre lines, plus
//!   the true parameters.
//! - Board-only views at random camera poses for detection tests ([`views`]).
//! - Line profilers ([`profiler`], issue 18): profiles `(x, z)` of a reference sphere on
//!   its stand and table, written as a profile dataset and scan.
//! - Verification artefacts: a ball bar in 7 positions and a flat plate in 3, with their
//!   certificate `artefacts.json` ([`verify`]).
//!
//! ## Conventions
//!
//! Those of the core crate (`stripecal`): mm, degrees in files, `T_a_b` maps b to a,
//! pixel centres at integer coordinates.

pub mod bench;
pub mod bench_scan;
pub mod bench_write;
pub mod config;
pub mod dataset;
pub mod imaging;
pub mod poses;
pub mod poses_wide;
pub mod profiler;
pub mod profiler_poses;
pub mod profiler_write;
pub mod render;
pub mod rng;
pub mod robot_error;
pub mod scene;
pub mod surface;
pub mod table_scan;
pub mod target;
pub mod truth;
pub mod verify;
pub mod views;

pub use config::{SimConfig, PRESETS};
pub use dataset::{noisy_observations, DatasetSummary, Twin, ViewRender};
pub use surface::{surface_errors, TablePlane};
pub use verify::{Artefacts, VerifyCfg, VerifyScan};

/// Errors of the twin.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// A knob with an invalid value (the message names it).
    #[error("configuration: {0}")]
    Config(String),
    /// No pose set satisfies the constraints.
    #[error("poses: {0}")]
    Poses(String),
    /// Rendering failed (e.g. a pixel outside the distortion model's valid zone).
    #[error("render: {0}")]
    Render(String),
    /// Writing the dataset failed.
    #[error(transparent)]
    Core(#[from] stripecal::Error),
}
