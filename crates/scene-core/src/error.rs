//! Typed errors. Each names the file, mesh, triangle, material or light at fault.

use std::path::PathBuf;

use crate::budget::BudgetError;

/// A scene that breaks an invariant diffuse transport relies on.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum SceneError {
    /// A vertex position is NaN or infinite.
    #[error("{mesh}: vertex {vertex} has a non-finite position")]
    NonFinitePosition {
        /// The mesh at fault.
        mesh: String,
        /// The vertex index.
        vertex: usize,
    },
    /// A vertex attribute is NaN or infinite (or, for colours, outside [0, 1]).
    #[error("{mesh}: vertex {vertex} has non-finite {attribute}")]
    NonFiniteAttribute {
        /// The mesh at fault.
        mesh: String,
        /// Which attribute.
        attribute: &'static str,
        /// The vertex index.
        vertex: usize,
    },
    /// An attribute array does not have one entry per vertex.
    #[error("{mesh}: {found} {attribute} for {expected} vertices")]
    AttributeCountMismatch {
        /// The mesh at fault.
        mesh: String,
        /// Which attribute.
        attribute: &'static str,
        /// Vertex count.
        expected: usize,
        /// Attribute count.
        found: usize,
    },
    /// A triangle index points past the vertex array.
    #[error(
        "{mesh}: triangle {triangle} uses vertex {index} but the mesh has {vertex_count} vertices"
    )]
    IndexOutOfRange {
        /// The mesh at fault.
        mesh: String,
        /// The triangle index.
        triangle: usize,
        /// The bad index.
        index: u32,
        /// Number of vertices in the mesh.
        vertex_count: usize,
    },
    /// The per-triangle material array has the wrong length.
    #[error("{mesh}: {material_ids} material ids for {triangles} triangles")]
    MaterialCountMismatch {
        /// The mesh at fault.
        mesh: String,
        /// Triangle count.
        triangles: usize,
        /// Material id count.
        material_ids: usize,
    },
    /// A triangle names a material that does not exist.
    #[error(
        "{mesh}: triangle {triangle} uses material {material} but the scene has {material_count}"
    )]
    MaterialOutOfRange {
        /// The mesh at fault.
        mesh: String,
        /// The triangle index.
        triangle: usize,
        /// The bad material id.
        material: u32,
        /// Number of materials.
        material_count: usize,
    },
    /// Albedo must lie in [0, [`crate::scene::ALBEDO_MAX`]]: radiosity diverges at 1.
    #[error(
        "{material}: albedo {albedo:?} is outside [0, {max}] (radiosity diverges at albedo 1)",
        max = crate::scene::ALBEDO_MAX
    )]
    AlbedoOutOfRange {
        /// The material at fault.
        material: String,
        /// Its albedo.
        albedo: [f32; 3],
    },
    /// Emission must be finite and non-negative.
    #[error("{material}: emission {emission:?} is negative or not finite")]
    InvalidEmission {
        /// The material at fault.
        material: String,
        /// Its emission.
        emission: [f32; 3],
    },
    /// A material's alpha cutoff is negative or not finite.
    #[error("{material}: {reason}")]
    InvalidMaterial {
        /// The material at fault.
        material: String,
        /// What is wrong.
        reason: String,
    },
    /// A material names a texture that does not exist.
    #[error("{material}: texture {texture} does not exist (the scene has {texture_count})")]
    TextureOutOfRange {
        /// The material at fault.
        material: String,
        /// The bad texture index.
        texture: u32,
        /// Number of textures.
        texture_count: usize,
    },
    /// A texture is malformed.
    #[error("{texture}: {reason}")]
    InvalidTexture {
        /// The texture at fault.
        texture: String,
        /// What is wrong.
        reason: String,
    },
    /// A light has invalid data.
    #[error("{light}: {reason}")]
    InvalidLight {
        /// The light at fault.
        light: String,
        /// What is wrong.
        reason: String,
    },
    /// A camera is degenerate (zero view direction, up parallel to it, bad fov or planes).
    #[error("{camera}: degenerate camera: {reason}")]
    InvalidCamera {
        /// The camera at fault.
        camera: String,
        /// What is wrong.
        reason: String,
    },
    /// The scene has no triangle a method could render (none given, or every one dropped
    /// as degenerate by validation).
    #[error("scene '{scene}' has no geometry: {reason}")]
    NoGeometry {
        /// The scene's name.
        scene: String,
        /// What it has instead.
        reason: String,
    },
    /// A number of the scene lies outside the range the toolkit accepts.
    #[error("{what} = {value:e} is outside the accepted range [{min}, {max:e}]")]
    OutOfRange {
        /// The number at fault (which material, light or camera, and which field).
        what: String,
        /// Its value.
        value: f32,
        /// The smallest accepted value.
        min: f32,
        /// The largest accepted value.
        max: f32,
    },
    /// The scene's coordinates are so large for its size that f32 no longer resolves its
    /// geometry (spacing above [`crate::contract::PRECISION_LIMIT`] of the extent).
    #[error(
        "scene '{scene}': geometry lies {offset:.3e} from the origin with an extent of only \
         {extent:.3e}: f32 places its vertices {spacing:.3e} apart there, more than {limit:e} \
         of the extent (the positions have already lost that precision); move the scene to \
         the origin where it is made",
        spacing = (offset.abs() + extent) * f32::EPSILON,
        limit = crate::contract::PRECISION_LIMIT
    )]
    PrecisionLost {
        /// The scene's name.
        scene: String,
        /// Distance of the geometry's centre from the origin.
        offset: f32,
        /// The geometry's extent (diagonal of its bounds).
        extent: f32,
    },
    /// A name given to `builtin` is unknown or its parameter is out of range.
    #[error(
        "unknown built-in scene '{0}' (known: cornell, cornell-point, primitives, corridor, many-boxes N)"
    )]
    UnknownBuiltin(String),
}

/// Reading or writing a glTF file failed.
#[derive(Debug, thiserror::Error)]
pub enum GltfError {
    /// The file could not be parsed or its buffers could not be loaded.
    #[error("{path}: cannot read glTF: {message}")]
    Read {
        /// The file.
        path: PathBuf,
        /// What the parser said.
        message: String,
    },
    /// The file parsed but its content is unusable.
    #[error("{path}: {message}")]
    Content {
        /// The file.
        path: PathBuf,
        /// What is wrong, naming the mesh/primitive/material.
        message: String,
    },
    /// The imported scene failed validation.
    #[error("{path}: {source}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The validation error.
        source: SceneError,
    },
    /// An external file the glTF names was refused: outside the scene's folder, absolute,
    /// not a regular file, or of an unsupported scheme.
    #[error("{path}: refused URI '{uri}': {reason}")]
    RefusedUri {
        /// The glTF file.
        path: PathBuf,
        /// The URI as written in the file (cut to 200 characters).
        uri: String,
        /// Why it was refused.
        reason: String,
    },
    /// The file asks for more memory than the budget allows (checked before allocating).
    #[error(transparent)]
    Budget(#[from] BudgetError),
    /// Writing failed.
    #[error("{path}: cannot write: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
}

/// Reading or writing an image failed.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// Decoding failed (unreadable, truncated or unsupported file).
    #[error("{path}: cannot read image: {message}")]
    Read {
        /// The file.
        path: PathBuf,
        /// What the decoder said.
        message: String,
    },
    /// A decoder in a dependency panicked on this file; the panic was caught.
    #[error(
        "{path}: the image decoder failed on this file (a fault in the decoder, caught): {message}"
    )]
    DecoderFault {
        /// The file.
        path: PathBuf,
        /// The decoder's panic message.
        message: String,
    },
    /// The image asks for more memory than the budget allows (checked before allocating).
    #[error(transparent)]
    Budget(#[from] BudgetError),
    /// Encoding or writing failed.
    #[error("{path}: cannot write image: {message}")]
    Write {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The file's format needs a cargo feature of scene-core this build was made without
    /// (`exr`).
    #[error(
        "{path}: reading this format needs scene-core's `{feature}` feature, which this build lacks"
    )]
    NotBuiltIn {
        /// The file.
        path: PathBuf,
        /// The missing feature.
        feature: &'static str,
    },
    /// The image has a zero dimension.
    #[error("image has zero size ({width}x{height})")]
    ZeroSize {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// Two images that must match do not.
    #[error("image sizes differ: {a:?} vs {b:?}")]
    SizeMismatch {
        /// First size.
        a: (u32, u32),
        /// Second size.
        b: (u32, u32),
    },
    /// The pixel buffer does not match the dimensions.
    #[error("{found} pixels for a {width}x{height} image")]
    BadLength {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
        /// Pixels supplied.
        found: usize,
    },
}

/// A computation that would exceed a budget (memory, element count, texels, an adapter's
/// binding limit), refused before anything was allocated. The method crates' `Budget`
/// errors carry one, so a caller reads the figures instead of parsing a message.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BudgetExceeded {
    /// What was to be allocated (`"a 4-light solution over 1200 elements"`).
    pub what: String,
    /// How much it needed.
    pub needed: u64,
    /// The limit.
    pub limit: u64,
    /// The unit of both: `"bytes"`, `"elements"` or `"texels"`.
    pub unit: &'static str,
    /// Which setting or limit it was, and what to change.
    pub hint: String,
}

impl std::fmt::Display for BudgetExceeded {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} needs {} {}, over the limit of {} ({})",
            self.what, self.needed, self.unit, self.limit, self.hint
        )
    }
}

impl std::error::Error for BudgetExceeded {}
