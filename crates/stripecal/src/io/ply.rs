use super::Cloud;
use crate::error::{Error, Result};
use std::path::Path;
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PlyFormat {
    #[default]
    BinaryLittleEndian,
    Ascii,
}
fn todo() -> Error {
    Error::InvalidInput("not yet implemented".into())
}
pub fn read_ply(_p: impl AsRef<Path>) -> Result<Cloud> {
    Err(todo())
}
pub fn write_ply(_p: impl AsRef<Path>, _c: &Cloud, _f: PlyFormat) -> Result<()> {
    Err(todo())
}
