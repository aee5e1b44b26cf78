use super::{Calibration, SphereFit, Truth};
use crate::error::{Error, Result};
use std::path::Path;
fn todo() -> Error {
    Error::InvalidInput("not yet implemented".into())
}
pub fn calibration_from_json(_path: &Path, _text: &str) -> Result<Calibration> {
    Err(todo())
}
pub fn calibration_to_json(_c: &Calibration) -> String {
    String::new()
}
pub fn read_calibration(_p: impl AsRef<Path>) -> Result<Calibration> {
    Err(todo())
}
pub fn write_calibration(_p: impl AsRef<Path>, _c: &Calibration) -> Result<()> {
    Err(todo())
}
pub fn truth_from_json(_path: &Path, _text: &str) -> Result<Truth> {
    Err(todo())
}
pub fn truth_to_json(_t: &Truth) -> String {
    String::new()
}
pub fn read_truth(_p: impl AsRef<Path>) -> Result<Truth> {
    Err(todo())
}
pub fn write_truth(_p: impl AsRef<Path>, _t: &Truth) -> Result<()> {
    Err(todo())
}
pub fn read_sphere_fit(_p: impl AsRef<Path>) -> Result<SphereFit> {
    Err(todo())
}
pub fn write_sphere_fit(_p: impl AsRef<Path>, _s: &SphereFit) -> Result<()> {
    Err(todo())
}
