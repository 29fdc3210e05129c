//! Cross-crate golden tests of the diffuse-GI toolkit. The tests live in `tests/tests/`;
//! this library only re-exports the crates they compose.

pub use scene_core;
