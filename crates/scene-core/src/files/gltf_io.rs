//! glTF 2.0 import and export (`.gltf` with embedded data URIs, and `.glb`).
//!
//! Only what diffuse transport needs is imported; everything else is listed in
//! [`ImportResult::ignored`] (one entry per ignored thing, `"<kind>: <detail>"`), and
//! [`ImportResult::summary`] condenses that list into one line.
//!
//! # Import
//!
//! * The default scene is used, or the first one; with no scene at all, every root node.
//!   Node transforms are flattened (`world = parent * local`): positions become world-space,
//!   normals are transformed by the inverse-transpose and renormalised, and a transform with
//!   a negative determinant flips the triangle winding. Every (node, mesh) pair becomes one
//!   [`Mesh`](crate::Mesh) named after the node (else the glTF mesh); its primitives are concatenated in
//!   order, so triangle order is the file's order.
//! * `TRIANGLES`, `TRIANGLE_STRIP` and `TRIANGLE_FAN` primitives are imported (strips and
//!   fans are converted to triangle lists). **Point and line primitives are skipped** and
//!   listed in `ignored` (they are not an error). Primitives without indices get sequential
//!   ones. An index past the primitive's vertex count is a [`GltfError::Content`](crate::GltfError::Content) naming the
//!   mesh and primitive.
//! * A primitive without `NORMAL` gets flat normals, as glTF 2.0 requires of a client: each
//!   triangle gets three vertices of its own carrying its face normal (the vertex budget is
//!   charged for them before reading). Zero or non-finite normals in a file are left for
//!   [`Scene::validate`](crate::Scene::validate) to recompute. Texture coordinates are read only
//!   for primitives whose material has a `baseColorTexture` (from the set that texture
//!   names, normally `TEXCOORD_0`).
//! * Materials are imported in file order (scene material `i` is glTF material `i`);
//!   primitives without a material share an extra default material (albedo 0.8 grey).
//!   albedo = `baseColorFactor.rgb`, clamped to at most [`ALBEDO_MAX`] per channel with a
//!   warning (glTF's default factor is 1, where radiosity diverges); emission =
//!   `emissiveFactor x KHR_materials_emissive_strength`, times the `emissiveTexture` where
//!   there is one ([`crate::Material::emission_texture`]; it reads the base colour's texture
//!   coordinates, or its own without a base colour texture). Textures are decoded
//!   (PNG or JPEG) and converted from sRGB to linear; only textures used that way are
//!   imported, in glTF texture index order. A base colour texture's `KHR_texture_transform`
//!   (offset, rotation, scale, and the coordinate set it names) is baked into the
//!   primitive's texture coordinates. A texture's sampler gives its [`crate::Wrap`] per
//!   axis and, from `magFilter`, nearest or bilinear lookups ([`crate::Sampler`]).
//! * `COLOR_0` (RGB or RGBA, float or normalised integers; clamped to [0, 1]) becomes
//!   [`crate::Mesh::colors`], multiplying the albedo; its alpha is not read.
//! * `alphaMode: MASK` becomes [`crate::Material::alpha_cutoff`] = `alphaCutoff` (default
//!   0.5) / `baseColorFactor.a` (above 1, any value up to 2, when the factor leaves no
//!   surface), and the base colour texture keeps its alpha channel ([`crate::Texture::alpha`],
//!   linear): every method sees holes where the alpha falls below the cutoff. `BLEND` is
//!   read as a mask at 0.5 and listed among the ignored; `OPAQUE` ignores alpha, as glTF
//!   says.
//! * `KHR_lights_punctual`: point lights keep `color x intensity` (candela) and `range` as the
//!   windowed-falloff radius; spot lights are point lights with a
//!   [`crate::lights::SpotCone`] (`innerConeAngle`, default 0, and `outerConeAngle`,
//!   default pi/4, about the node's world -Z; angles outside `0 <= inner <= outer <= pi/2`
//!   are refused by validation, naming the light); directional lights travel along the
//!   node's world -Z with irradiance `color x intensity` (lux).
//! * Perspective cameras: eye at the node's world origin, looking along its world -Z with its
//!   world +Y as up; `aspectRatio` defaults to 1; a missing `zfar` (infinite projection)
//!   becomes `max(1000 znear, 2 (distance to the scene's centre + scene extent))`. The
//!   target lies `extras.target_distance` (written by [`export`]) or 1 along the view
//!   direction. Orthographic cameras are ignored; a camera without the projection object its
//!   type names is a [`GltfError::Read`](crate::GltfError::Read).
//! * Animations, skins (meshes are taken in their node's rest transform), morph targets,
//!   vertex colour sets past `COLOR_0`, metallic/roughness, normal/occlusion textures, blending (see
//!   above),
//!   other scenes and any extension but the three above are ignored and listed.
//!   Minification filters are not used (textures have no mipmaps).
//! * The scene is then checked with [`Scene::validate`](crate::Scene::validate) ([`GltfError::Invalid`](crate::GltfError::Invalid) on failure;
//!   dropped degenerate triangles become warnings). Unreadable, truncated or corrupted files
//!   and out-of-range buffer data give [`GltfError::Read`](crate::GltfError::Read); nothing panics (accessors are
//!   checked against their buffers before the `gltf` readers touch them, and a few inputs
//!   on which `gltf` 1.4 itself would panic are rejected first).
//! * Nothing is allocated from the file's word before it is charged to the
//!   [`ImportOptions::budget`]: buffers (by their size or their data URI's), textures (by
//!   their header's size, before decoding), vertices and indices after instancing (by the
//!   accessors' counts, before reading). Exceeding it is a [`GltfError::Budget`](crate::GltfError::Budget).
//! * Buffers and images named by URI are read by [`ExternalFiles`] policy: by default only
//!   regular files inside the glTF's folder (symbolic links followed); absolute paths,
//!   `..` out of the folder, devices and other schemes are a [`GltfError::RefusedUri`](crate::GltfError::RefusedUri).
//!
//! # Export
//!
//! [`export`] writes `.gltf` (JSON, buffer embedded as a base64 data URI) or `.glb` (binary
//! chunk) by the file extension, through a temporary file renamed into place. Each non-empty
//! [`Mesh`](crate::Mesh) becomes one node and one glTF mesh with **one primitive per contiguous run of
//! triangles with the same material**, so triangle order (and thus triangle ids) survives a
//! round trip; each primitive carries only the vertices its triangles use (shared vertices
//! at a material boundary are duplicated). Attributes are `POSITION` (with min/max),
//! `NORMAL` (as repaired by [`Scene::validate`](crate::Scene::validate)), `TEXCOORD_0` when the mesh has UVs and
//! `COLOR_0` when it has vertex colours;
//! indices are `u32`. Materials carry `baseColorFactor` (alpha 1), `metallicFactor` 0,
//! `roughnessFactor` 1, the albedo and emission textures as embedded sRGB PNGs (RGBA with linear
//! alpha when it has alpha), `alphaMode: MASK` with the cutoff when masked, and `emissiveFactor`
//! (normalised to a maximum of 1, with `KHR_materials_emissive_strength` carrying the scale
//! when emission exceeds 1). Point, spot and directional lights use `KHR_lights_punctual`;
//! cameras are perspective camera nodes whose rotation points -Z at the target, with the
//! target distance in the node's extras. Empty meshes and unreferenced textures are not
//! written.

mod export;
mod import;
#[cfg(test)]
mod tests;
mod uri;

pub use export::{VertexAttribute, export, export_with};
pub use import::{
    ImportOptions, ImportResult, import, import_slice, import_slice_with, import_with,
};
pub use uri::ExternalFiles;

/// Imported albedo channels are clamped to at most this value, the largest albedo a scene
/// may have ([`crate::scene::ALBEDO_MAX`]).
pub use crate::scene::ALBEDO_MAX;

/// Albedo of the material given to primitives that have none.
pub const DEFAULT_ALBEDO: f32 = 0.8;

/// Name of the material given to primitives that have none.
pub const DEFAULT_MATERIAL_NAME: &str = "default";

/// Key of the camera node extras that carries the distance to the camera target.
const TARGET_DISTANCE_KEY: &str = "target_distance";

const EXT_LIGHTS: &str = "KHR_lights_punctual";
const EXT_EMISSIVE_STRENGTH: &str = "KHR_materials_emissive_strength";
const EXT_TEXTURE_TRANSFORM: &str = "KHR_texture_transform";
