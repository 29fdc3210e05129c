//! The scene model: what diffuse transport needs of a scene ([`scene`]: meshes, diffuse
//! materials, albedo textures, lights, cameras), the built-in test scenes ([`builtin`]),
//! light sources with stable ids and their per-frame state ([`lights`]), and views
//! ([`view`]: cameras, hemicube faces, shadow-map views, engine matrices), the scene
//! contract every method holds ([`contract`]), the sky ([`sky`]), and alpha-masked surfaces as visibility
//! sees them ([`cutout`]).

pub mod building;
pub mod builtin;
pub mod contract;
pub mod cutout;
pub mod lights;
pub mod scene;
pub mod sky;
pub mod view;
