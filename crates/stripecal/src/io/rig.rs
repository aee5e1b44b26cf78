use super::Rig;
use crate::error::{Error, Result};
use std::path::Path;
fn todo() -> Error {
    Error::InvalidInput("not yet implemented".into())
}
pub fn rig_from_json(_path: &Path, _text: &str) -> Result<Rig> {
    Err(todo())
}
pub fn rig_to_json(_r: &Rig) -> String {
    String::new()
}
pub fn read_rig(_p: impl AsRef<Path>) -> Result<Rig> {
    Err(todo())
}
pub fn write_rig(_p: impl AsRef<Path>, _r: &Rig) -> Result<()> {
    Err(todo())
}
