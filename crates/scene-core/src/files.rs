//! Files: glTF import and export ([`gltf_io`]), linear-RGB images and EXR/PNG I/O
//! ([`image`]), the budgets every loader charges before it allocates ([`budget`]), and
//! opening a scene by name or path ([`open`]).

pub mod budget;
#[cfg(feature = "gltf")]
pub mod gltf_io;
pub mod image;
pub mod open;
