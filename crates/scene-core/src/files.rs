//! Files: glTF import and export ([`gltf_io`]), linear-RGB images and EXR/PNG I/O
//! ([`image`]), and the budgets every loader charges before it allocates ([`budget`]).

pub mod budget;
pub mod gltf_io;
pub mod image;
