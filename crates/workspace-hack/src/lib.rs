//! No code. This crate only declares dependencies with the union of the features that
//! the wheel's build (`stripecal-py`) and `cargo test` (the default members with their
//! dev-dependencies) enable, so both builds share every compiled dependency in `target/`.
//! See its Cargo.toml.
