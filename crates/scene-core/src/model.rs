//! The scene model: what diffuse transport needs of a scene ([`scene`]: meshes, diffuse
//! materials, albedo textures, lights, cameras), the built-in test scenes ([`builtin`]),
//! light sources with stable ids and their per-frame state ([`lights`]), and views
//! ([`view`]: cameras, hemicube faces, shadow-map views, engine matrices), and the scene
//! contract every method holds ([`contract`]).

pub mod building;
pub mod builtin;
pub mod contract;
pub mod lights;
pub mod scene;
pub mod view;
