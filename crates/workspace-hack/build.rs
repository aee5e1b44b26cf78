//! Empty: the build script exists so that its build-dependencies (syn with the features
//! pyo3's macros use) join the host side's feature resolution (see Cargo.toml).
fn main() {}
