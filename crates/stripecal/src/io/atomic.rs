use crate::error::Result;
use std::path::Path;
/// TEMPORARY signature stub (io helper implements).
pub fn write_atomic(path: impl AsRef<Path>, bytes: &[u8]) -> Result<()> {
    let path = path.as_ref();
    std::fs::write(path, bytes).map_err(|e| crate::Error::io(path, e))
}
