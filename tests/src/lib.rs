//! Cross-crate golden tests of the diffuse-GI toolkit. The tests live in `tests/tests/`;
//! this library holds what they and `cargo xtask fuzz` share: hostile files written by code
//! ([`hostile`]), the fuzz targets and their seeds ([`fuzz`]), and running a test's body in a
//! child process under a memory limit ([`child`]).

pub mod child;
pub mod fuzz;
pub mod hostile;
pub mod scenes;

pub use scene_core;
