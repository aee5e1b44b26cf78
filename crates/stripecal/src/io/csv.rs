use super::{ScanFrame, View};
use crate::error::{Error, Result};
use crate::kinematics::Robot;
use std::path::Path;
fn todo() -> Error {
    Error::InvalidInput("not yet implemented".into())
}
pub fn read_views_csv(_p: impl AsRef<Path>, _robot: Option<&Robot>) -> Result<Vec<View>> {
    Err(todo())
}
pub fn write_views_csv(_p: impl AsRef<Path>, _views: &[View]) -> Result<()> {
    Err(todo())
}
pub fn read_scan_csv(_p: impl AsRef<Path>, _robot: Option<&Robot>) -> Result<Vec<ScanFrame>> {
    Err(todo())
}
pub fn write_scan_csv(_p: impl AsRef<Path>, _frames: &[ScanFrame]) -> Result<()> {
    Err(todo())
}
