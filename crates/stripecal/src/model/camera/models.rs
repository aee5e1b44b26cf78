//! The camera-model seam: a projection model is one file implementing [`CameraModel`]
//! plus its registration, like the pose conventions of `io::poses`.
//!
//! Every model is a pinhole (`u = fu xd + u0`, `v = fv yd + v0`, no skew) after a
//! distortion of the normalised coordinates `(x, y) = (xc / zc, yc / zc)` with the
//! model's own coefficients. A model says its coefficients' names (so its parameter
//! vector is `fu, fv, u0, v0` then those: its count and layout, which the joint
//! adjustment's camera block takes), the distortion with its Jacobian with respect to
//! the point and to the coefficients (analytic), and which coefficients a calibration
//! estimates. Undistortion, projection and their Jacobians follow from these
//! ([`super::Camera`]); a model whose distortion is the identity at all-zero
//! coefficients gets the exact shortcut there.
//!
//! A camera names its model by a [`Projection`] (default `brown5`, [`super::brown5`]).
//! A new model is one file with a type implementing [`CameraModel`], and either one
//! entry in [`BUILTIN`] (a model of the library) or one call of [`register`] (a model
//! added from outside, as the integration tests' toy model is); [`projection`] finds
//! either by name.

use std::sync::RwLock;

use nalgebra::{Matrix2, Matrix2xX};

use super::brown5::{Brown5, DISTORTION_NAMES};
use super::DistortionModel;
use crate::error::{Error, Result};

/// Most distortion coefficients a camera stores (`Camera::distortion`'s length; a model
/// with more needs this raised and the files' `distortion` arrays with it, see
/// docs/architecture.md).
pub const MAX_DISTORTION: usize = 5;

/// A projection model: pinhole after a distortion of normalised coordinates (module
/// docs).
pub trait CameraModel: Sync + Send {
    /// The name in files and messages (`brown5`).
    fn name(&self) -> &'static str;
    /// Names of the distortion coefficients, in the order the camera stores them
    /// (at most [`MAX_DISTORTION`]).
    fn distortion_names(&self) -> &'static [&'static str];
    /// Distorted normalised coordinates of `(x, y)` and the Jacobian
    /// `d(xd, yd) / d(x, y)`; `k` holds [`Self::distortion_names`]'s coefficients.
    fn distort(&self, k: &[f64], x: f64, y: f64) -> ((f64, f64), Matrix2<f64>);
    /// `d(xd, yd) / d(k)` at `(x, y)`: 2 rows, one column per coefficient.
    fn distortion_jacobian(&self, k: &[f64], x: f64, y: f64) -> Matrix2xX<f64>;
    /// Which coefficients a calibration estimates when `choice` is asked for
    /// (`brown5` reads it; another model may estimate all of its coefficients).
    fn free_coefficients(&self, choice: DistortionModel) -> Vec<bool> {
        let _ = choice;
        vec![true; self.distortion_names().len()]
    }

    /// Number of distortion coefficients.
    fn distortion_count(&self) -> usize {
        self.distortion_names().len()
    }
    /// Number of camera parameters: `fu, fv, u0, v0` and the coefficients.
    fn param_count(&self) -> usize {
        4 + self.distortion_count()
    }
    /// Names of the camera parameters, in the order of the model's parameter vector
    /// (`fu, fv, u0, v0`, then [`Self::distortion_names`]).
    fn param_names(&self) -> Vec<&'static str> {
        let mut v = vec!["fu", "fv", "u0", "v0"];
        v.extend_from_slice(self.distortion_names());
        v
    }
}

/// Which model a camera has: `brown5` (the default, inlined where it is evaluated per
/// point) or another registered one.
#[derive(Clone, Copy, Default)]
pub enum Projection {
    /// [`Brown5`].
    #[default]
    Brown5,
    /// Any other model ([`BUILTIN`] or [`register`]).
    Other(&'static dyn CameraModel),
}

impl Projection {
    /// The model.
    pub fn model(&self) -> &'static dyn CameraModel {
        match self {
            Projection::Brown5 => &Brown5,
            Projection::Other(m) => *m,
        }
    }

    /// The model's name.
    pub fn name(&self) -> &'static str {
        self.model().name()
    }

    /// Whether it is `brown5`.
    pub fn is_brown5(&self) -> bool {
        matches!(self, Projection::Brown5)
    }
}

impl std::fmt::Debug for Projection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl PartialEq for Projection {
    fn eq(&self, other: &Self) -> bool {
        self.name() == other.name()
    }
}

/// The library's models other than `brown5` (which [`Projection::Brown5`] is): a new
/// one is an entry here.
pub static BUILTIN: [&dyn CameraModel; 0] = [];

/// Models registered at run time ([`register`]).
static REGISTERED: RwLock<Vec<&'static dyn CameraModel>> = RwLock::new(Vec::new());

/// Registers a model so [`projection`] finds it by name; registering the same name
/// again is allowed for the same object only. Errors on a model with more than
/// [`MAX_DISTORTION`] coefficients.
pub fn register(model: &'static dyn CameraModel) -> Result<Projection> {
    let name = model.name();
    if model.distortion_count() > MAX_DISTORTION {
        return Err(Error::InvalidInput(format!(
            "camera model {name:?} has {} distortion coefficients: at most {MAX_DISTORTION}",
            model.distortion_count()
        )));
    }
    if let Ok(p) = projection(name) {
        return match p {
            Projection::Other(m) if std::ptr::addr_eq(m as *const _, model as *const _) => Ok(p),
            _ => Err(Error::InvalidInput(format!(
                "camera model {name:?} is registered already"
            ))),
        };
    }
    let mut reg = REGISTERED.write().unwrap_or_else(|e| e.into_inner());
    reg.push(model);
    Ok(Projection::Other(model))
}

/// The model of a name: `brown5`, a [`BUILTIN`] one or a [`register`]ed one.
pub fn projection(name: &str) -> Result<Projection> {
    if name == Brown5.name() {
        return Ok(Projection::Brown5);
    }
    if let Some(m) = BUILTIN.iter().find(|m| m.name() == name) {
        return Ok(Projection::Other(*m));
    }
    let reg = REGISTERED.read().unwrap_or_else(|e| e.into_inner());
    reg.iter()
        .find(|m| m.name() == name)
        .map(|m| Projection::Other(*m))
        .ok_or_else(|| {
            Error::InvalidInput(format!(
                "unknown camera model {name:?}: known are {}",
                model_names().join(", ")
            ))
        })
}

/// The names of every known model, `brown5` first.
pub fn model_names() -> Vec<&'static str> {
    let mut v = vec![Brown5.name()];
    v.extend(BUILTIN.iter().map(|m| m.name()));
    let reg = REGISTERED.read().unwrap_or_else(|e| e.into_inner());
    v.extend(reg.iter().map(|m| m.name()));
    v
}

const _: () = assert!(DISTORTION_NAMES.len() <= MAX_DISTORTION);
