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
//!   [`Mesh`] named after the node (else the glTF mesh); its primitives are concatenated in
//!   order, so triangle order is the file's order.
//! * `TRIANGLES`, `TRIANGLE_STRIP` and `TRIANGLE_FAN` primitives are imported (strips and
//!   fans are converted to triangle lists). **Point and line primitives are skipped** and
//!   listed in `ignored` (they are not an error). Primitives without indices get sequential
//!   ones. An index past the primitive's vertex count is a [`GltfError::Content`] naming the
//!   mesh and primitive.
//! * Missing normals are left for [`Scene::validate`] to recompute (the `normals` vector is
//!   left empty when no primitive of a mesh has normals). Texture coordinates are read only
//!   for primitives whose material has a `baseColorTexture` (from the set that texture
//!   names, normally `TEXCOORD_0`).
//! * Materials are imported in file order (scene material `i` is glTF material `i`);
//!   primitives without a material share an extra default material (albedo 0.8 grey).
//!   albedo = `baseColorFactor.rgb`, clamped to at most [`ALBEDO_MAX`] per channel with a
//!   warning (glTF's default factor is 1, where radiosity diverges); emission =
//!   `emissiveFactor x KHR_materials_emissive_strength`. `baseColorTexture`s are decoded
//!   (PNG or JPEG) and converted from sRGB to linear; only textures used that way are
//!   imported, in glTF texture index order.
//! * `KHR_lights_punctual`: point lights keep `color x intensity` (candela) and `range` as the
//!   windowed-falloff radius; spot lights become point lights with a warning; directional
//!   lights travel along the node's world -Z with irradiance `color x intensity` (lux).
//! * Perspective cameras: eye at the node's world origin, looking along its world -Z with its
//!   world +Y as up; `aspectRatio` defaults to 1; a missing `zfar` (infinite projection)
//!   becomes `max(1000 znear, 2 (distance to the scene's centre + scene extent))`. The
//!   target lies `extras.target_distance` (written by [`export`]) or 1 along the view
//!   direction. Orthographic cameras are ignored; a camera without the projection object its
//!   type names is a [`GltfError::Read`].
//! * Animations, skins (meshes are taken in their node's rest transform), morph targets,
//!   vertex colours, metallic/roughness, normal/occlusion/emissive textures, transparency,
//!   non-default samplers, other scenes and any extension but the two above are ignored and
//!   listed.
//! * The scene is then checked with [`Scene::validate`] ([`GltfError::Invalid`] on failure;
//!   dropped degenerate triangles become warnings). Unreadable, truncated or corrupted files
//!   and out-of-range buffer data give [`GltfError::Read`]; nothing panics (accessors are
//!   checked against their buffers before the `gltf` readers touch them, and a few inputs
//!   on which `gltf` 1.4 itself would panic are rejected first).
//! * Nothing is allocated from the file's word before it is charged to the
//!   [`ImportOptions::budget`]: buffers (by their size or their data URI's), textures (by
//!   their header's size, before decoding), vertices and indices after instancing (by the
//!   accessors' counts, before reading). Exceeding it is a [`GltfError::Budget`].
//! * Buffers and images named by URI are read by [`ExternalFiles`] policy: by default only
//!   regular files inside the glTF's folder (symbolic links followed); absolute paths,
//!   `..` out of the folder, devices and other schemes are a [`GltfError::RefusedUri`].
//!
//! # Export
//!
//! [`export`] writes `.gltf` (JSON, buffer embedded as a base64 data URI) or `.glb` (binary
//! chunk) by the file extension, through a temporary file renamed into place. Each non-empty
//! [`Mesh`] becomes one node and one glTF mesh with **one primitive per contiguous run of
//! triangles with the same material**, so triangle order (and thus triangle ids) survives a
//! round trip; each primitive carries only the vertices its triangles use (shared vertices
//! at a material boundary are duplicated). Attributes are `POSITION` (with min/max),
//! `NORMAL` (as repaired by [`Scene::validate`]) and `TEXCOORD_0` when the mesh has UVs;
//! indices are `u32`. Materials carry `baseColorFactor` (alpha 1), `metallicFactor` 0,
//! `roughnessFactor` 1, the albedo texture as an embedded sRGB PNG, and `emissiveFactor`
//! (normalised to a maximum of 1, with `KHR_materials_emissive_strength` carrying the scale
//! when emission exceeds 1). Point and directional lights use `KHR_lights_punctual`;
//! cameras are perspective camera nodes whose rotation points -Z at the target, with the
//! target distance in the node's extras. Empty meshes and unreferenced textures are not
//! written.

use std::borrow::Cow;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use base64::Engine as _;
use glam::{Mat3, Mat4, Quat, Vec2, Vec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::khr_lights_punctual::Kind as LightKind;
use gltf::mesh::Mode;
use serde_json::{Value, json};

use crate::budget::{Allowance, Budget};
use crate::error::{GltfError, ImageError};
use crate::image::{Image, linear_to_srgb};
use crate::scene::{
    Camera, DirectionalLight, Material, Mesh, PointLight, Scene, Texture, label_or_index,
};

/// Imported albedo channels are clamped to at most this value (validation requires < 1).
pub const ALBEDO_MAX: f32 = 0.999;

/// Albedo of the material given to primitives that have none.
pub const DEFAULT_ALBEDO: f32 = 0.8;

/// Name of the material given to primitives that have none.
pub const DEFAULT_MATERIAL_NAME: &str = "default";

mod uri;
pub use uri::ExternalFiles;

/// Key of the camera node extras that carries the distance to the camera target.
const TARGET_DISTANCE_KEY: &str = "target_distance";

const EXT_LIGHTS: &str = "KHR_lights_punctual";
const EXT_EMISSIVE_STRENGTH: &str = "KHR_materials_emissive_strength";

const GL_ARRAY_BUFFER: u32 = 34962;
const GL_ELEMENT_ARRAY_BUFFER: u32 = 34963;
const GL_FLOAT: u32 = 5126;
const GL_UNSIGNED_INT: u32 = 5125;
const GL_LINEAR: u32 = 9729;
const GL_REPEAT: u32 = 10497;

/// What [`import`] produced: the scene plus what was left out and what was adjusted.
#[derive(Clone, Debug)]
pub struct ImportResult {
    /// The validated scene (named after the file stem).
    pub scene: Scene,
    /// Features of the file that were not imported, one entry each, as `"<kind>: <detail>"`
    /// (for example `"animation: 'Walk'"`).
    pub ignored: Vec<String>,
    /// Adjustments made while importing (clamped albedo, spot lights imported as point
    /// lights, dropped degenerate triangles, ...).
    pub warnings: Vec<String>,
}

/// How [`import_with`] treats what a file asks for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ImportOptions {
    /// Limits on what the file may make the importer allocate: file and buffer sizes, decoded
    /// textures, vertices and indices after instancing, and the scene's total bytes. Each is
    /// checked before the allocation; exceeding one gives [`GltfError::Budget`].
    pub budget: Budget,
    /// Where external buffers and images may be read from (default: the scene's folder
    /// only); a refused URI gives [`GltfError::RefusedUri`].
    pub external_files: ExternalFiles,
}

impl ImportResult {
    /// One line counting what was ignored, by kind, in order of first appearance, e.g.
    /// `"ignored: 3 metallic-roughness textures, 1 spot cone (imported as point light), 2
    /// animations"`, or `"ignored: nothing"`.
    pub fn summary(&self) -> String {
        let mut counts: Vec<(&str, usize)> = Vec::new();
        for entry in &self.ignored {
            let kind = entry.split_once(": ").map_or(entry.as_str(), |(k, _)| k);
            match counts.iter_mut().find(|(k, _)| *k == kind) {
                Some((_, n)) => *n += 1,
                None => counts.push((kind, 1)),
            }
        }
        if counts.is_empty() {
            return "ignored: nothing".to_string();
        }
        let parts: Vec<String> = counts
            .iter()
            .map(|&(kind, n)| {
                if n == 1 {
                    format!("1 {kind}")
                } else {
                    format!("{n} {}", Ignored::plural_of(kind))
                }
            })
            .collect();
        format!("ignored: {}", parts.join(", "))
    }
}

/// Kinds of ignored features (singular form is the prefix of an `ignored` entry).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Ignored {
    Animation,
    Skin,
    MorphTargets,
    VertexColors,
    NonTriangles,
    MetallicRoughness,
    MetallicRoughnessTexture,
    NormalTexture,
    OcclusionTexture,
    EmissiveTexture,
    Sampler,
    Transparency,
    SpotCone,
    OrthographicCamera,
    Extension,
    OtherScene,
}

impl Ignored {
    const ALL: [Ignored; 16] = [
        Ignored::Animation,
        Ignored::Skin,
        Ignored::MorphTargets,
        Ignored::VertexColors,
        Ignored::NonTriangles,
        Ignored::MetallicRoughness,
        Ignored::MetallicRoughnessTexture,
        Ignored::NormalTexture,
        Ignored::OcclusionTexture,
        Ignored::EmissiveTexture,
        Ignored::Sampler,
        Ignored::Transparency,
        Ignored::SpotCone,
        Ignored::OrthographicCamera,
        Ignored::Extension,
        Ignored::OtherScene,
    ];

    fn forms(self) -> (&'static str, &'static str) {
        match self {
            Ignored::Animation => ("animation", "animations"),
            Ignored::Skin => ("skin", "skins"),
            Ignored::MorphTargets => ("morph target set", "morph target sets"),
            Ignored::VertexColors => ("vertex colour set", "vertex colour sets"),
            Ignored::NonTriangles => ("point/line primitive", "point/line primitives"),
            Ignored::MetallicRoughness => {
                ("metallic/roughness setting", "metallic/roughness settings")
            }
            Ignored::MetallicRoughnessTexture => {
                ("metallic-roughness texture", "metallic-roughness textures")
            }
            Ignored::NormalTexture => ("normal texture", "normal textures"),
            Ignored::OcclusionTexture => ("occlusion texture", "occlusion textures"),
            Ignored::EmissiveTexture => ("emissive texture", "emissive textures"),
            Ignored::Sampler => (
                "sampler setting (bilinear/repeat used)",
                "sampler settings (bilinear/repeat used)",
            ),
            Ignored::Transparency => ("transparency setting", "transparency settings"),
            Ignored::SpotCone => (
                "spot cone (imported as point light)",
                "spot cones (imported as point lights)",
            ),
            Ignored::OrthographicCamera => ("orthographic camera", "orthographic cameras"),
            Ignored::Extension => ("extension", "extensions"),
            Ignored::OtherScene => ("other scene", "other scenes"),
        }
    }

    fn plural_of(singular: &str) -> String {
        Ignored::ALL
            .iter()
            .map(|k| k.forms())
            .find(|(s, _)| *s == singular)
            .map_or_else(|| format!("{singular}s"), |(_, p)| p.to_string())
    }
}

// ---------------------------------------------------------------------------------------------
// Import
// ---------------------------------------------------------------------------------------------

/// Imports a `.gltf` (with embedded or external buffers and images) or `.glb` file.
///
/// See the [module documentation](self) for what is imported and what is ignored.
/// Errors: [`GltfError::Read`] when the file cannot be read or parsed or its buffers are
/// missing, truncated or inconsistent; [`GltfError::Content`] for unusable content (wrong
/// accessor types, indices past the vertex count, a cyclic node hierarchy);
/// [`GltfError::Invalid`] when the imported scene fails [`Scene::validate`].
pub fn import(path: &Path) -> Result<ImportResult, GltfError> {
    import_with(path, &ImportOptions::default())
}

/// [`import`] with explicit [`ImportOptions`] (budget and external-file policy).
pub fn import_with(path: &Path, options: &ImportOptions) -> Result<ImportResult, GltfError> {
    let bytes = crate::budget::read_file(path, &options.budget).map_err(|e| match e {
        crate::budget::ReadFileError::Budget(b) => GltfError::Budget(b),
        other => read_error(path, other.to_string()),
    })?;
    let base = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    import_bytes(&bytes, Some(base), path, options)
}

/// Imports a self-contained glTF from memory: a `.glb`, or a `.gltf` whose buffers and
/// images are data URIs (external references give [`GltfError::RefusedUri`]), under the
/// default [`ImportOptions`]. `name_for_errors` names the data in errors, and its stem
/// names the scene.
pub fn import_slice(bytes: &[u8], name_for_errors: &Path) -> Result<ImportResult, GltfError> {
    import_slice_with(bytes, name_for_errors, &ImportOptions::default())
}

/// [`import_slice`] with explicit [`ImportOptions`].
pub fn import_slice_with(
    bytes: &[u8],
    name_for_errors: &Path,
    options: &ImportOptions,
) -> Result<ImportResult, GltfError> {
    import_bytes(bytes, None, name_for_errors, options)
}

fn read_error(path: &Path, message: impl Into<String>) -> GltfError {
    GltfError::Read {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

fn content_error(path: &Path, message: impl Into<String>) -> GltfError {
    GltfError::Content {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

fn import_bytes(
    bytes: &[u8],
    base: Option<&Path>,
    path: &Path,
    options: &ImportOptions,
) -> Result<ImportResult, GltfError> {
    let mut allowance = Allowance::new(options.budget, path);
    // The file itself, and its JSON once parsed: each JSON object becomes a Rust struct of
    // at most a few hundred bytes, so 512 bytes an object (counted by its opening brace)
    // bounds what parsing allocates, before it does.
    let json = json_part(bytes);
    let objects = json.iter().filter(|&&b| b == b'{').count() as u64;
    allowance.charge_bytes(bytes.len() as u64, || "the file".into())?;
    allowance.charge_bytes(objects.saturating_mul(JSON_OBJECT_BYTES), || {
        format!("its JSON once parsed ({objects} objects)")
    })?;
    let (document, blob) = parse_document(bytes).map_err(|m| read_error(path, m))?;
    let uris = uri::UriReader {
        path,
        base,
        policy: options.external_files,
    };
    let buffers = load_buffers(&document, blob, &uris, &mut allowance)?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut importer = Importer {
        path,
        uris,
        allowance,
        doc: &document,
        buffers: &buffers,
        scene: Scene::new(&name),
        ignored: Vec::new(),
        warnings: Vec::new(),
        default_material: None,
        pending_far: Vec::new(),
    };
    importer.run()?;
    let Importer {
        mut scene,
        ignored,
        mut warnings,
        ..
    } = importer;
    let report = scene.validate().map_err(|source| GltfError::Invalid {
        path: path.to_path_buf(),
        source,
    })?;
    for (mesh, n) in &report.degenerate_dropped {
        warnings.push(format!("{mesh}: {n} degenerate triangles dropped"));
    }
    Ok(ImportResult {
        scene,
        ignored,
        warnings,
    })
}

/// Bytes charged for each JSON object of a glTF before it is parsed (an upper bound of the
/// size of the `gltf-json` struct it becomes, with its vectors and maps).
const JSON_OBJECT_BYTES: u64 = 512;

/// The JSON of a glTF: the whole file, or a GLB's first chunk (as far as the file holds).
fn json_part(bytes: &[u8]) -> &[u8] {
    if !bytes.starts_with(b"glTF") {
        return bytes;
    }
    let len = bytes
        .get(12..16)
        .map_or(0, |b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
    let end = 20usize.saturating_add(len).min(bytes.len());
    bytes.get(20..end).unwrap_or(&[])
}

/// Loads every buffer (GLB chunk, data URI or external file under the URI policy), each
/// charged to the allowance before it is read, and checks it holds its `byteLength`.
fn load_buffers(
    document: &gltf::Document,
    mut blob: Option<Vec<u8>>,
    uris: &uri::UriReader,
    allowance: &mut Allowance,
) -> Result<Vec<gltf::buffer::Data>, GltfError> {
    let path = uris.path;
    let mut buffers = Vec::with_capacity(document.buffers().len());
    for buffer in document.buffers() {
        let what = format!("buffer {}", buffer.index());
        let mut data = match buffer.source() {
            gltf::buffer::Source::Bin => {
                let bin = blob.take().ok_or_else(|| {
                    read_error(path, format!("{what}: the file has no binary chunk"))
                })?;
                allowance.charge_bytes(bin.len() as u64, || what.clone())?;
                bin
            }
            gltf::buffer::Source::Uri(u) => uris.read(u, &what, allowance)?,
        };
        if data.len() < buffer.length() {
            return Err(read_error(
                path,
                format!(
                    "{what}: {} bytes, but byteLength says {}",
                    data.len(),
                    buffer.length()
                ),
            ));
        }
        data.resize(data.len().next_multiple_of(4), 0);
        buffers.push(gltf::buffer::Data(data));
    }
    Ok(buffers)
}

/// Parses and validates the document, rejecting first the inputs on which `gltf` 1.4
/// would panic (a GLB length below the header size, a `POSITION` accessor index out of
/// range, images without a source or MIME type, cameras without the projection their type
/// names).
fn parse_document(bytes: &[u8]) -> Result<(gltf::Document, Option<Vec<u8>>), String> {
    if bytes.starts_with(b"glTF") {
        let length = bytes
            .get(8..12)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .ok_or("GLB header truncated")?;
        if length < 12 {
            return Err(format!("GLB header declares a length of {length} bytes"));
        }
    }
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| e.to_string())?;
    let root = document.into_json();
    precheck(&root)?;
    let document = gltf::Document::from_json(root).map_err(|e| e.to_string())?;
    Ok((document, blob))
}

fn precheck(root: &gltf::json::Root) -> Result<(), String> {
    let accessors = root.accessors.len();
    for (mi, mesh) in root.meshes.iter().enumerate() {
        for (pi, prim) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &prim.attributes {
                if index.value() >= accessors {
                    let name = match semantic {
                        gltf::json::validation::Checked::Valid(s) => s.to_string(),
                        gltf::json::validation::Checked::Invalid => "?".to_string(),
                    };
                    return Err(format!(
                        "mesh {mi} primitive {pi}: attribute {name} uses accessor {} but the \
                         file has {accessors}",
                        index.value()
                    ));
                }
            }
        }
    }
    for (i, image) in root.images.iter().enumerate() {
        match (&image.buffer_view, &image.uri) {
            (Some(_), _) if image.mime_type.is_none() => {
                return Err(format!("image {i}: bufferView without mimeType"));
            }
            (None, None) => return Err(format!("image {i}: neither uri nor bufferView")),
            _ => {}
        }
    }
    // `gltf` unwraps the projection object that the camera's type names.
    for (i, camera) in root.cameras.iter().enumerate() {
        use gltf::json::camera::Type;
        use gltf::json::validation::Checked;
        let present = match camera.type_ {
            Checked::Valid(Type::Perspective) => camera.perspective.is_some(),
            Checked::Valid(Type::Orthographic) => camera.orthographic.is_some(),
            Checked::Invalid => false,
        };
        if !present {
            let ty = match camera.type_ {
                Checked::Valid(Type::Perspective) => "perspective",
                Checked::Valid(Type::Orthographic) => "orthographic",
                Checked::Invalid => "an unknown type",
            };
            return Err(format!(
                "camera {i}: its type is {ty} but it has no {ty} object"
            ));
        }
    }
    Ok(())
}

/// Why an accessor cannot be read: its bytes are out of range, or its type is wrong.
enum AccessorProblem {
    Range(String),
    Kind(String),
}

fn view_bytes<'b>(
    view: &gltf::buffer::View,
    buffers: &'b [gltf::buffer::Data],
) -> Result<&'b [u8], String> {
    let data = buffers
        .get(view.buffer().index())
        .ok_or_else(|| format!("buffer {} not loaded", view.buffer().index()))?;
    view.offset()
        .checked_add(view.length())
        .and_then(|end| data.0.get(view.offset()..end))
        .ok_or_else(|| {
            format!(
                "buffer view {} ({} bytes at {}) lies outside buffer {} ({} bytes)",
                view.index(),
                view.length(),
                view.offset(),
                view.buffer().index(),
                data.0.len()
            )
        })
}

/// Checks that `count` elements of `elem` bytes at `offset` in `view` (with the view's
/// stride) lie inside the loaded buffer, as `gltf`'s readers assume.
fn check_range(
    view: &gltf::buffer::View,
    offset: usize,
    count: usize,
    elem: usize,
    buffers: &[gltf::buffer::Data],
) -> Result<(), String> {
    if count == 0 {
        return Err("count is 0".into());
    }
    let stride = view.stride().unwrap_or(elem);
    if stride < elem {
        return Err(format!(
            "byteStride {stride} is below the element size {elem}"
        ));
    }
    let bytes = view_bytes(view, buffers)?;
    let end = stride
        .checked_mul(count - 1)
        .and_then(|x| x.checked_add(elem))
        .and_then(|x| x.checked_add(offset));
    match end {
        Some(end) if end <= bytes.len() => Ok(()),
        _ => Err(format!(
            "{count} elements of {elem} bytes (stride {stride}) at offset {offset} overrun buffer \
             view {} ({} bytes)",
            view.index(),
            bytes.len()
        )),
    }
}

fn check_accessor(
    acc: &gltf::Accessor,
    types: &[DataType],
    dims: Dimensions,
    buffers: &[gltf::buffer::Data],
) -> Result<(), AccessorProblem> {
    if !types.contains(&acc.data_type()) || acc.dimensions() != dims {
        return Err(AccessorProblem::Kind(format!(
            "is {:?} {:?}, expected {:?} of {:?}",
            acc.dimensions(),
            acc.data_type(),
            dims,
            types
        )));
    }
    let elem = acc.size();
    let count = acc.count();
    if count == 0 {
        return Err(AccessorProblem::Kind("count is 0".into()));
    }
    // A sparse-only accessor (no view) has nothing to range-check here; its count is
    // charged to the vertex budget before it is read.
    if let Some(view) = acc.view() {
        check_range(&view, acc.offset(), count, elem, buffers).map_err(AccessorProblem::Range)?;
    }
    if let Some(sparse) = acc.sparse() {
        let n = sparse.count();
        let indices = sparse.indices();
        let index_size = match indices.index_type() {
            gltf::accessor::sparse::IndexType::U8 => 1,
            gltf::accessor::sparse::IndexType::U16 => 2,
            gltf::accessor::sparse::IndexType::U32 => 4,
        };
        check_range(&indices.view(), indices.offset(), n, index_size, buffers)
            .map_err(|m| AccessorProblem::Range(format!("sparse indices: {m}")))?;
        let values = sparse.values();
        check_range(&values.view(), values.offset(), n, elem, buffers)
            .map_err(|m| AccessorProblem::Range(format!("sparse values: {m}")))?;
    }
    Ok(())
}

/// A camera whose far plane is computed once the scene's bounds are known.
struct PendingFar {
    camera: usize,
    near: f32,
}

struct Importer<'a> {
    path: &'a Path,
    uris: uri::UriReader<'a>,
    allowance: Allowance,
    doc: &'a gltf::Document,
    buffers: &'a [gltf::buffer::Data],
    scene: Scene,
    ignored: Vec<String>,
    warnings: Vec<String>,
    default_material: Option<u32>,
    pending_far: Vec<PendingFar>,
}

/// The vertex and triangle data of one primitive, in world space.
struct PrimitiveData {
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    uvs: Option<Vec<Vec2>>,
    triangles: Vec<[u32; 3]>,
    material: u32,
}

impl<'a> Importer<'a> {
    fn ignore(&mut self, kind: Ignored, detail: impl AsRef<str>) {
        self.ignored
            .push(format!("{}: {}", kind.forms().0, detail.as_ref()));
    }

    fn run(&mut self) -> Result<(), GltfError> {
        let doc = self.doc;
        for ext in doc.extensions_used() {
            if ext != EXT_LIGHTS && ext != EXT_EMISSIVE_STRENGTH {
                self.ignore(Ignored::Extension, ext);
            }
        }
        for (i, anim) in doc.animations().enumerate() {
            self.ignore(
                Ignored::Animation,
                label_or_index(anim.name().unwrap_or(""), "animation", i),
            );
        }
        for (i, skin) in doc.skins().enumerate() {
            self.ignore(
                Ignored::Skin,
                label_or_index(skin.name().unwrap_or(""), "skin", i),
            );
        }
        self.import_materials()?;

        let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
            Some(chosen) => {
                for other in doc.scenes().filter(|s| s.index() != chosen.index()) {
                    self.ignore(
                        Ignored::OtherScene,
                        label_or_index(other.name().unwrap_or(""), "scene", other.index()),
                    );
                }
                chosen.nodes().collect()
            }
            None => {
                let mut is_child = vec![false; doc.nodes().len()];
                for node in doc.nodes() {
                    for child in node.children() {
                        is_child[child.index()] = true;
                    }
                }
                if doc.nodes().len() > 0 {
                    self.warnings
                        .push("the file has no scene: importing every root node".into());
                }
                doc.nodes().filter(|n| !is_child[n.index()]).collect()
            }
        };

        let mut visited = vec![false; doc.nodes().len()];
        let mut stack: Vec<(gltf::Node, Mat4)> = roots
            .into_iter()
            .rev()
            .map(|n| (n, Mat4::IDENTITY))
            .collect();
        while let Some((node, parent)) = stack.pop() {
            if std::mem::replace(&mut visited[node.index()], true) {
                return Err(content_error(
                    self.path,
                    format!(
                        "node {} is reached twice: the node hierarchy has a cycle or a shared child",
                        node.index()
                    ),
                ));
            }
            let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
            self.visit(&node, world)?;
            let children: Vec<gltf::Node> = node.children().collect();
            for child in children.into_iter().rev() {
                stack.push((child, world));
            }
        }

        // Far planes of cameras with an infinite projection.
        let bounds = self.scene.bounds();
        let (center, extent) = if bounds.is_empty() {
            (Vec3::ZERO, 0.0)
        } else {
            (bounds.center(), bounds.diagonal())
        };
        for p in std::mem::take(&mut self.pending_far) {
            let cam = &mut self.scene.cameras[p.camera];
            let reach = 2.0 * (cam.position.distance(center) + extent);
            cam.far = (1000.0 * p.near).max(reach);
        }
        Ok(())
    }

    fn import_materials(&mut self) -> Result<(), GltfError> {
        let doc = self.doc;
        // Textures used as base colour, decoded in glTF texture index order.
        let used: BTreeSet<usize> = doc
            .materials()
            .filter_map(|m| m.pbr_metallic_roughness().base_color_texture())
            .map(|info| info.texture().index())
            .collect();
        let mut texture_map = BTreeMap::new();
        for t in used {
            let Some(texture) = doc.textures().nth(t) else {
                continue;
            };
            let decoded = self.decode_texture(&texture)?;
            texture_map.insert(t, self.scene.textures.len() as u32);
            self.scene.textures.push(decoded);
        }
        for (i, m) in doc.materials().enumerate() {
            let name = m.name().unwrap_or("").to_string();
            let label = label_or_index(&name, "material", i);
            let pbr = m.pbr_metallic_roughness();
            let f = pbr.base_color_factor();
            let mut albedo = Vec3::new(f[0], f[1], f[2]);
            if albedo.max_element() > ALBEDO_MAX {
                albedo = albedo.min(Vec3::splat(ALBEDO_MAX));
                self.warnings
                    .push(format!("{label}: albedo clamped below 1 (to {ALBEDO_MAX})"));
            }
            let albedo_texture = pbr
                .base_color_texture()
                .and_then(|info| texture_map.get(&info.texture().index()).copied());
            let emission = Vec3::from(m.emissive_factor()) * m.emissive_strength().unwrap_or(1.0);
            if pbr.metallic_roughness_texture().is_some() {
                self.ignore(Ignored::MetallicRoughnessTexture, &label);
            }
            if pbr.metallic_factor() > 0.0 || pbr.roughness_factor() < 1.0 {
                self.ignore(
                    Ignored::MetallicRoughness,
                    format!(
                        "{label} (metallic {}, roughness {})",
                        pbr.metallic_factor(),
                        pbr.roughness_factor()
                    ),
                );
            }
            if m.normal_texture().is_some() {
                self.ignore(Ignored::NormalTexture, &label);
            }
            if m.occlusion_texture().is_some() {
                self.ignore(Ignored::OcclusionTexture, &label);
            }
            if m.emissive_texture().is_some() {
                self.ignore(Ignored::EmissiveTexture, &label);
            }
            if f[3] < 1.0 || m.alpha_mode() != gltf::material::AlphaMode::Opaque {
                self.ignore(Ignored::Transparency, &label);
            }
            self.scene.materials.push(Material {
                name,
                albedo,
                albedo_texture,
                emission,
            });
        }
        Ok(())
    }

    fn decode_texture(&mut self, texture: &gltf::Texture) -> Result<Texture, GltfError> {
        use gltf::texture::{MagFilter, WrappingMode};
        let image = texture.source();
        let name = image
            .name()
            .or(texture.name())
            .map_or_else(|| format!("texture {}", texture.index()), str::to_string);
        let sampler = texture.sampler();
        if sampler.wrap_s() != WrappingMode::Repeat
            || sampler.wrap_t() != WrappingMode::Repeat
            || sampler.mag_filter() == Some(MagFilter::Nearest)
        {
            self.ignore(
                Ignored::Sampler,
                format!("texture {} '{name}'", texture.index()),
            );
        }
        let what = format!("texture {} '{name}'", texture.index());
        let path = self.path;
        let encoded: Cow<[u8]> = match image.source() {
            gltf::image::Source::View { view, .. } => Cow::Borrowed(
                view_bytes(&view, self.buffers)
                    .map_err(|m| read_error(path, format!("{what}: {m}")))?,
            ),
            gltf::image::Source::Uri { uri, .. } => {
                Cow::Owned(self.uris.read(uri, &what, &mut self.allowance)?)
            }
        };
        let image_error = |e: ImageError| match e {
            ImageError::Budget(mut b) => {
                b.what = format!("{what}: {}", b.what);
                GltfError::Budget(b)
            }
            other => read_error(path, format!("{what}: {other}")),
        };
        // The header's size is charged to the scene before the texels are decoded.
        let budget = *self.allowance.budget();
        let (w, h) = Image::probe_dimensions(&encoded, path, &budget).map_err(image_error)?;
        let texel_bytes = budget.check_image(u64::from(w), u64::from(h), 0, path, &what)?;
        self.allowance
            .charge_bytes(texel_bytes, || format!("{what}: {w}x{h} texels"))?;
        let decoded =
            Image::decode_texture(&encoded, path, self.allowance.budget()).map_err(image_error)?;
        Ok(Texture {
            name,
            width: decoded.width,
            height: decoded.height,
            texels: decoded.pixels,
        })
    }

    fn visit(&mut self, node: &gltf::Node, world: Mat4) -> Result<(), GltfError> {
        let node_name = node.name().unwrap_or("");
        if let Some(mesh) = node.mesh() {
            self.import_mesh(node_name, &mesh, world)?;
        }
        if let Some(camera) = node.camera() {
            let name = camera.name().unwrap_or(node_name).to_string();
            match camera.projection() {
                gltf::camera::Projection::Perspective(p) => {
                    let position = world.transform_point3(Vec3::ZERO);
                    let forward = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
                    let up = world
                        .transform_vector3(Vec3::Y)
                        .try_normalize()
                        .unwrap_or(Vec3::Y);
                    let distance = target_distance(node).unwrap_or(1.0);
                    let near = p.znear();
                    if p.zfar().is_none() {
                        self.pending_far.push(PendingFar {
                            camera: self.scene.cameras.len(),
                            near,
                        });
                    }
                    self.scene.cameras.push(Camera {
                        name,
                        position,
                        target: position + forward * distance,
                        up,
                        fov_y: p.yfov(),
                        aspect: p.aspect_ratio().unwrap_or(1.0),
                        near,
                        far: p.zfar().unwrap_or(1000.0 * near),
                    });
                }
                gltf::camera::Projection::Orthographic(_) => {
                    let label = label_or_index(&name, "camera", camera.index());
                    self.ignore(Ignored::OrthographicCamera, label);
                }
            }
        }
        if let Some(light) = node.light() {
            let name = light.name().unwrap_or(node_name).to_string();
            let power = Vec3::from(light.color()) * light.intensity();
            match light.kind() {
                LightKind::Directional => {
                    self.scene.directional_lights.push(DirectionalLight {
                        name,
                        direction: world.transform_vector3(Vec3::NEG_Z).normalize_or_zero(),
                        irradiance: power,
                    });
                }
                kind => {
                    if let LightKind::Spot { .. } = kind {
                        let label = label_or_index(&name, "light", light.index());
                        self.warnings.push(format!(
                            "{label}: spot light imported as a point light (cone ignored)"
                        ));
                        self.ignore(Ignored::SpotCone, label);
                    }
                    self.scene.point_lights.push(PointLight {
                        name,
                        position: world.transform_point3(Vec3::ZERO),
                        intensity: power,
                        radius: light.range(),
                    });
                }
            }
        }
        Ok(())
    }

    fn import_mesh(
        &mut self,
        node_name: &str,
        mesh: &gltf::Mesh,
        world: Mat4,
    ) -> Result<(), GltfError> {
        let name = if node_name.is_empty() {
            mesh.name().unwrap_or("").to_string()
        } else {
            node_name.to_string()
        };
        let label = label_or_index(mesh.name().unwrap_or(""), "glTF mesh", mesh.index());
        let linear = Mat3::from_mat4(world);
        let det = linear.determinant();
        let normal_matrix = if det != 0.0 && det.is_finite() {
            linear.inverse().transpose()
        } else {
            Mat3::ZERO
        };
        let flip = det < 0.0;

        let mut out = Mesh {
            name,
            ..Default::default()
        };
        let mut any_normals = false;
        for (pi, prim) in mesh.primitives().enumerate() {
            let Some(data) = self.read_primitive(&label, pi, &prim)? else {
                continue;
            };
            let base = out.positions.len();
            let total = base + data.positions.len();
            if u32::try_from(total).is_err() {
                return Err(content_error(
                    self.path,
                    format!("{label}: more than 2^32 vertices"),
                ));
            }
            let base = base as u32;
            out.positions
                .extend(data.positions.iter().map(|&p| world.transform_point3(p)));
            match data.normals {
                Some(normals) => {
                    any_normals = true;
                    out.normals.extend(normals.iter().map(|&n| {
                        let n = (normal_matrix * n).normalize_or_zero();
                        if n.is_finite() { n } else { Vec3::ZERO }
                    }));
                }
                // Zero normals are recomputed by validation.
                None => out.normals.resize(total, Vec3::ZERO),
            }
            match (data.uvs, &mut out.uvs) {
                (Some(uvs), Some(all)) => all.extend(uvs),
                (Some(uvs), None) => {
                    let mut all = vec![Vec2::ZERO; base as usize];
                    all.extend(uvs);
                    out.uvs = Some(all);
                }
                (None, Some(all)) => all.resize(total, Vec2::ZERO),
                (None, None) => {}
            }
            out.indices.extend(data.triangles.iter().map(|t| {
                let [a, b, c] = t.map(|i| i + base);
                if flip { [a, c, b] } else { [a, b, c] }
            }));
            out.material_ids
                .extend(std::iter::repeat_n(data.material, data.triangles.len()));
        }
        if !any_normals {
            out.normals.clear();
        }
        if !out.indices.is_empty() {
            self.scene.meshes.push(out);
        }
        Ok(())
    }

    fn default_material(&mut self) -> u32 {
        *self.default_material.get_or_insert_with(|| {
            self.scene.materials.push(Material::diffuse(
                DEFAULT_MATERIAL_NAME,
                Vec3::splat(DEFAULT_ALBEDO),
            ));
            self.scene.materials.len() as u32 - 1
        })
    }

    fn read_primitive(
        &mut self,
        label: &str,
        pi: usize,
        prim: &gltf::Primitive,
    ) -> Result<Option<PrimitiveData>, GltfError> {
        let at = format!("{label} primitive {pi}");
        let mode = prim.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            self.ignore(Ignored::NonTriangles, format!("{at} ({mode:?})"));
            return Ok(None);
        }
        if prim.morph_targets().next().is_some() {
            self.ignore(Ignored::MorphTargets, &at);
        }
        if prim.get(&gltf::Semantic::Colors(0)).is_some() {
            self.ignore(Ignored::VertexColors, &at);
        }
        let material = match prim.material().index() {
            Some(m) => m as u32,
            None => self.default_material(),
        };
        let tex_set = prim
            .material()
            .pbr_metallic_roughness()
            .base_color_texture()
            .map(|info| info.tex_coord());

        let buffers = self.buffers;
        let path = self.path;
        let check = |acc: &gltf::Accessor, what: &str, types: &[DataType], dims: Dimensions| {
            check_accessor(acc, types, dims, buffers).map_err(|p| match p {
                AccessorProblem::Range(m) => {
                    read_error(path, format!("{at}: {what} accessor {}: {m}", acc.index()))
                }
                AccessorProblem::Kind(m) => {
                    content_error(path, format!("{at}: {what} accessor {}: {m}", acc.index()))
                }
            })
        };
        let count_mismatch = |what: &str, found: usize, expected: usize| {
            read_error(
                path,
                format!("{at}: {found} {what} values read, {expected} expected"),
            )
        };

        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| d.0.as_slice()));
        let Some(pos_acc) = prim.get(&gltf::Semantic::Positions) else {
            return Err(content_error(path, format!("{at}: no POSITION attribute")));
        };
        check(&pos_acc, "POSITION", &[DataType::F32], Dimensions::Vec3)?;
        // Charge the primitive (vertices, indices and their bytes in the scene) before any
        // of it is read: counts come from the file and are not trusted.
        // Strips and fans of k indices make k - 2 triangles, lists k / 3.
        let n = pos_acc.count() as u64;
        let raw_indices = prim.indices().map_or(n, |a| a.count() as u64);
        let triangles = match mode {
            Mode::Triangles => raw_indices / 3,
            _ => raw_indices.saturating_sub(2),
        };
        let vertex_bytes = 12 + 12 + if tex_set.is_some() { 8 } else { 0 };
        // Bytes: the vertex arrays; the indices as read (4 each); per triangle its index
        // triple twice (primitive, then mesh) and its material id.
        self.allowance.charge_mesh(
            n,
            triangles.saturating_mul(3),
            n.saturating_mul(vertex_bytes)
                .saturating_add(raw_indices.saturating_mul(4))
                .saturating_add(triangles.saturating_mul(12 + 12 + 4)),
            || at.clone(),
        )?;
        // Every other attribute must have one value per vertex before it is read: the
        // `gltf` readers size their output from the accessor's count (a sparse-only
        // accessor has no buffer to bound it).
        let same_count = |acc: &gltf::Accessor, what: &str| {
            if acc.count() as u64 == n {
                Ok(())
            } else {
                Err(read_error(
                    path,
                    format!(
                        "{at}: {what} accessor {} has {} values for {n} vertices",
                        acc.index(),
                        acc.count()
                    ),
                ))
            }
        };
        let positions: Vec<Vec3> = reader
            .read_positions()
            .map(|it| it.map(Vec3::from).collect())
            .unwrap_or_default();
        let n = pos_acc.count();
        if positions.len() != n {
            return Err(count_mismatch("POSITION", positions.len(), n));
        }

        let normals = match prim.get(&gltf::Semantic::Normals) {
            Some(acc) => {
                check(&acc, "NORMAL", &[DataType::F32], Dimensions::Vec3)?;
                same_count(&acc, "NORMAL")?;
                let normals: Vec<Vec3> = reader
                    .read_normals()
                    .map(|it| it.map(Vec3::from).collect())
                    .unwrap_or_default();
                if normals.len() != n {
                    return Err(count_mismatch("NORMAL", normals.len(), n));
                }
                Some(normals)
            }
            None => None,
        };

        let uvs = match tex_set {
            Some(set) => match prim.get(&gltf::Semantic::TexCoords(set)) {
                Some(acc) => {
                    let what = format!("TEXCOORD_{set}");
                    check(
                        &acc,
                        &what,
                        &[DataType::F32, DataType::U8, DataType::U16],
                        Dimensions::Vec2,
                    )?;
                    same_count(&acc, &what)?;
                    let uvs: Vec<Vec2> = reader
                        .read_tex_coords(set)
                        .map(|it| it.into_f32().map(Vec2::from).collect())
                        .unwrap_or_default();
                    if uvs.len() != n {
                        return Err(count_mismatch(&what, uvs.len(), n));
                    }
                    Some(uvs)
                }
                None => {
                    self.warnings.push(format!(
                        "{at}: the material has a base colour texture but there is no \
                         TEXCOORD_{set}; texture coordinates set to 0"
                    ));
                    Some(vec![Vec2::ZERO; n])
                }
            },
            None => None,
        };

        let indices: Vec<u32> = match prim.indices() {
            Some(acc) => {
                check(
                    &acc,
                    "index",
                    &[DataType::U8, DataType::U16, DataType::U32],
                    Dimensions::Scalar,
                )?;
                let indices: Vec<u32> = reader
                    .read_indices()
                    .map(|it| it.into_u32().collect())
                    .unwrap_or_default();
                if indices.len() != acc.count() {
                    return Err(count_mismatch("index", indices.len(), acc.count()));
                }
                if let Some(bad) = indices.iter().find(|&&i| i as usize >= n) {
                    return Err(content_error(
                        path,
                        format!("{at}: index {bad} is past the primitive's {n} vertices"),
                    ));
                }
                indices
            }
            None => {
                let n32 = u32::try_from(n)
                    .map_err(|_| content_error(path, format!("{at}: too many vertices")))?;
                (0..n32).collect()
            }
        };
        let triangles = triangulate(mode, &indices);
        if mode == Mode::Triangles && !indices.len().is_multiple_of(3) {
            self.warnings.push(format!(
                "{at}: {} indices is not a multiple of 3; the last {} ignored",
                indices.len(),
                indices.len() % 3
            ));
        }
        Ok(Some(PrimitiveData {
            positions,
            normals,
            uvs,
            triangles,
            material,
        }))
    }
}

/// Converts a triangle list, strip or fan into triangles (glTF 2.0 spec, 3.7.2.1).
fn triangulate(mode: Mode, idx: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::TriangleStrip => (0..idx.len().saturating_sub(2))
            .map(|i| {
                if i % 2 == 0 {
                    [idx[i], idx[i + 1], idx[i + 2]]
                } else {
                    [idx[i], idx[i + 2], idx[i + 1]]
                }
            })
            .collect(),
        Mode::TriangleFan => (0..idx.len().saturating_sub(2))
            .map(|i| [idx[i + 1], idx[i + 2], idx[0]])
            .collect(),
        _ => idx.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
    }
}

fn target_distance(node: &gltf::Node) -> Option<f32> {
    let raw = node.extras().as_ref()?;
    let value: Value = serde_json::from_str(raw.get()).ok()?;
    let d = value.get(TARGET_DISTANCE_KEY)?.as_f64()? as f32;
    (d.is_finite() && d > 0.0).then_some(d)
}

// ---------------------------------------------------------------------------------------------
// Export
// ---------------------------------------------------------------------------------------------

/// Exports a scene as `.gltf` (JSON with the buffer embedded as a base64 data URI) or `.glb`,
/// chosen by the extension of `path` (case-insensitive).
///
/// The scene must pass [`Scene::validate`] (checked on a copy; the file is written from the
/// original, so triangle order and ids are kept) or [`GltfError::Invalid`] is returned. See
/// the [module documentation](self) for the layout. I/O failures and an unknown extension
/// give [`GltfError::Write`]; a failed write leaves no partial file at `path`.
pub fn export(scene: &Scene, path: &Path) -> Result<(), GltfError> {
    let binary = match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("gltf") => false,
        Some("glb") => true,
        _ => {
            return Err(write_error(
                path,
                std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    "the file extension must be .gltf or .glb",
                ),
            ));
        }
    };
    let mut checked = scene.clone();
    checked.validate().map_err(|source| GltfError::Invalid {
        path: path.to_path_buf(),
        source,
    })?;
    let (mut root, bin) = build_document(scene, &checked).map_err(|m| write_error(path, m))?;
    let bytes = if binary {
        if !bin.is_empty() {
            root["buffers"] = json!([{ "byteLength": bin.len() }]);
        }
        let json_bytes = serde_json::to_vec(&root).map_err(|e| write_error(path, e))?;
        if json_bytes.len() as u64 + bin.len() as u64 + 28 > u64::from(u32::MAX) {
            return Err(write_error(
                path,
                "the scene is too large for a .glb (4 GiB)",
            ));
        }
        let glb = gltf::binary::Glb {
            header: gltf::binary::Header {
                magic: *b"glTF",
                version: 2,
                length: 0, // computed by the writer
            },
            json: Cow::Owned(json_bytes),
            bin: (!bin.is_empty()).then_some(Cow::Owned(bin)),
        };
        glb.to_vec().map_err(|e| write_error(path, e.to_string()))?
    } else {
        if !bin.is_empty() {
            let uri = format!(
                "data:application/octet-stream;base64,{}",
                base64::engine::general_purpose::STANDARD.encode(&bin)
            );
            root["buffers"] = json!([{ "byteLength": bin.len(), "uri": uri }]);
        }
        serde_json::to_vec_pretty(&root).map_err(|e| write_error(path, e))?
    };
    write_file_atomically(path, &bytes)
}

fn write_error(path: &Path, e: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> GltfError {
    GltfError::Write {
        path: path.to_path_buf(),
        source: std::io::Error::other(e),
    }
}

fn write_file_atomically(path: &Path, bytes: &[u8]) -> Result<(), GltfError> {
    let write_error = |source| GltfError::Write {
        path: path.to_path_buf(),
        source,
    };
    crate::image::write_via_temp(
        path,
        |tmp| std::fs::write(tmp, bytes).map_err(write_error),
        write_error,
    )
}

/// The binary buffer with its buffer views and accessors.
#[derive(Default)]
struct BinWriter {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl BinWriter {
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        self.pad();
        let mut view = json!({
            "buffer": 0,
            "byteOffset": self.bin.len(),
            "byteLength": bytes.len(),
        });
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.pad();
        self.views.push(view);
        self.views.len() - 1
    }

    fn pad(&mut self) {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
    }

    fn floats(&mut self, values: impl Iterator<Item = f32>, count: usize, ty: &str) -> Value {
        let bytes: Vec<u8> = values.flat_map(f32::to_le_bytes).collect();
        let view = self.view(&bytes, Some(GL_ARRAY_BUFFER));
        json!({
            "bufferView": view,
            "componentType": GL_FLOAT,
            "count": count,
            "type": ty,
        })
    }

    fn push(&mut self, accessor: Value) -> usize {
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    fn vec3(&mut self, data: &[Vec3], bounds: bool) -> usize {
        let mut acc = self.floats(data.iter().flat_map(|v| v.to_array()), data.len(), "VEC3");
        if bounds {
            let min = data.iter().fold(Vec3::INFINITY, |a, &b| a.min(b));
            let max = data.iter().fold(Vec3::NEG_INFINITY, |a, &b| a.max(b));
            acc["min"] = json!(min.to_array());
            acc["max"] = json!(max.to_array());
        }
        self.push(acc)
    }

    fn vec2(&mut self, data: &[Vec2]) -> usize {
        let acc = self.floats(data.iter().flat_map(|v| v.to_array()), data.len(), "VEC2");
        self.push(acc)
    }

    fn indices(&mut self, data: &[u32]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(GL_ELEMENT_ARRAY_BUFFER));
        self.push(json!({
            "bufferView": view,
            "componentType": GL_UNSIGNED_INT,
            "count": data.len(),
            "type": "SCALAR",
        }))
    }
}

/// Splits a non-negative colour into a `[0, 1]` colour and a scale (its maximum channel).
fn split_scale(c: Vec3) -> ([f32; 3], f32) {
    let m = c.max_element();
    if m > 0.0 {
        ((c / m).min(Vec3::ONE).to_array(), m)
    } else {
        ([1.0, 1.0, 1.0], 0.0)
    }
}

fn named(mut v: Value, name: &str) -> Value {
    if !name.is_empty() {
        v["name"] = json!(name);
    }
    v
}

/// Builds the glTF JSON (without `buffers`) and the binary buffer. `checked` is the
/// validated copy of `scene` (same vertices, repaired normals).
fn build_document(scene: &Scene, checked: &Scene) -> Result<(Value, Vec<u8>), String> {
    let mut w = BinWriter::default();
    let mut extensions_used: BTreeSet<&str> = BTreeSet::new();

    // Textures referenced by materials, in index order, embedded as sRGB PNGs.
    let referenced: BTreeSet<u32> = scene
        .materials
        .iter()
        .filter_map(|m| m.albedo_texture)
        .collect();
    let mut texture_map = BTreeMap::new();
    let mut images = Vec::new();
    let mut textures = Vec::new();
    for &t in &referenced {
        let tex = &scene.textures[t as usize];
        let png = encode_png(tex).map_err(|e| format!("texture {t} '{}': {e}", tex.name))?;
        let view = w.view(&png, None);
        images.push(named(
            json!({ "bufferView": view, "mimeType": "image/png" }),
            &tex.name,
        ));
        texture_map.insert(t, textures.len());
        textures.push(named(
            json!({ "source": images.len() - 1, "sampler": 0 }),
            &tex.name,
        ));
    }

    let materials: Vec<Value> = scene
        .materials
        .iter()
        .map(|m| {
            let mut pbr = json!({
                "baseColorFactor": [m.albedo.x, m.albedo.y, m.albedo.z, 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 1.0,
            });
            if let Some(t) = m.albedo_texture.and_then(|t| texture_map.get(&t)) {
                pbr["baseColorTexture"] = json!({ "index": t });
            }
            let mut mat = named(json!({ "pbrMetallicRoughness": pbr }), &m.name);
            if m.emission.max_element() > 1.0 {
                let (factor, strength) = split_scale(m.emission);
                mat["emissiveFactor"] = json!(factor);
                mat["extensions"] =
                    json!({ EXT_EMISSIVE_STRENGTH: { "emissiveStrength": strength } });
                extensions_used.insert(EXT_EMISSIVE_STRENGTH);
            } else if m.is_emissive() {
                mat["emissiveFactor"] = json!(m.emission.to_array());
            }
            mat
        })
        .collect();

    let mut meshes = Vec::new();
    let mut nodes = Vec::new();
    for (mesh, fixed) in scene.meshes.iter().zip(&checked.meshes) {
        if mesh.indices.is_empty() {
            continue;
        }
        let uvs = mesh
            .uvs
            .as_ref()
            .filter(|uvs| uvs.len() == mesh.positions.len());
        let mut primitives = Vec::new();
        let mut start = 0;
        while start < mesh.indices.len() {
            let material = mesh.material_ids[start];
            let mut end = start + 1;
            while end < mesh.indices.len() && mesh.material_ids[end] == material {
                end += 1;
            }
            let run = &mesh.indices[start..end];
            // Compact to the vertices this run uses, keeping their relative order.
            let mut used: Vec<u32> = run.iter().flatten().copied().collect();
            used.sort_unstable();
            used.dedup();
            let local = |v: u32| used.binary_search(&v).unwrap_or_else(|i| i) as u32;
            let idx: Vec<u32> = run.iter().flatten().map(|&v| local(v)).collect();
            let positions: Vec<Vec3> = used.iter().map(|&v| mesh.positions[v as usize]).collect();
            let normals: Vec<Vec3> = used.iter().map(|&v| fixed.normals[v as usize]).collect();
            let mut attributes = json!({
                "POSITION": w.vec3(&positions, true),
                "NORMAL": w.vec3(&normals, false),
            });
            if let Some(uvs) = uvs {
                let uv: Vec<Vec2> = used.iter().map(|&v| uvs[v as usize]).collect();
                attributes["TEXCOORD_0"] = json!(w.vec2(&uv));
            }
            primitives.push(json!({
                "attributes": attributes,
                "indices": w.indices(&idx),
                "material": material,
                "mode": 4,
            }));
            start = end;
        }
        meshes.push(named(json!({ "primitives": primitives }), &mesh.name));
        nodes.push(named(json!({ "mesh": meshes.len() - 1 }), &mesh.name));
    }

    let mut lights = Vec::new();
    for l in &scene.point_lights {
        let (color, intensity) = split_scale(l.intensity);
        let mut light = named(
            json!({ "type": "point", "color": color, "intensity": intensity }),
            &l.name,
        );
        if let Some(r) = l.radius {
            light["range"] = json!(r);
        }
        lights.push(light);
        nodes.push(named(
            json!({
                "translation": l.position.to_array(),
                "extensions": { EXT_LIGHTS: { "light": lights.len() - 1 } },
            }),
            &l.name,
        ));
    }
    for l in &scene.directional_lights {
        let (color, intensity) = split_scale(l.irradiance);
        lights.push(named(
            json!({ "type": "directional", "color": color, "intensity": intensity }),
            &l.name,
        ));
        let rotation = Quat::from_rotation_arc(Vec3::NEG_Z, l.direction.normalize()).normalize();
        nodes.push(named(
            json!({
                "rotation": rotation.to_array(),
                "extensions": { EXT_LIGHTS: { "light": lights.len() - 1 } },
            }),
            &l.name,
        ));
    }
    if !lights.is_empty() {
        extensions_used.insert(EXT_LIGHTS);
    }

    let mut cameras = Vec::new();
    for c in &scene.cameras {
        let offset = c.target - c.position;
        let forward = offset.normalize();
        let right = forward.cross(c.up).normalize();
        let up = right.cross(forward);
        let rotation = Quat::from_mat3(&Mat3::from_cols(right, up, -forward)).normalize();
        cameras.push(named(
            json!({
                "type": "perspective",
                "perspective": {
                    "yfov": c.fov_y,
                    "aspectRatio": c.aspect,
                    "znear": c.near,
                    "zfar": c.far,
                },
            }),
            &c.name,
        ));
        nodes.push(named(
            json!({
                "camera": cameras.len() - 1,
                "translation": c.position.to_array(),
                "rotation": rotation.to_array(),
                "extras": { TARGET_DISTANCE_KEY: offset.length() },
            }),
            &c.name,
        ));
    }

    let mut root = json!({
        "asset": { "version": "2.0", "generator": "scene-core gltf_io" },
        "scene": 0,
        "scenes": [named(json!({ "nodes": (0..nodes.len()).collect::<Vec<_>>() }), &scene.name)],
    });
    let mut set = |key: &str, v: Vec<Value>| {
        if !v.is_empty() {
            root[key] = Value::Array(v);
        }
    };
    set("nodes", nodes);
    set("meshes", meshes);
    set("materials", materials);
    set("cameras", cameras);
    set("images", images);
    let has_textures = !textures.is_empty();
    set("textures", textures);
    if has_textures {
        root["samplers"] = json!([{
            "magFilter": GL_LINEAR,
            "minFilter": GL_LINEAR,
            "wrapS": GL_REPEAT,
            "wrapT": GL_REPEAT,
        }]);
    }
    if !lights.is_empty() {
        root["extensions"] = json!({ EXT_LIGHTS: { "lights": lights } });
    }
    if !extensions_used.is_empty() {
        root["extensionsUsed"] = json!(extensions_used.into_iter().collect::<Vec<_>>());
    }
    if !w.views.is_empty() {
        root["bufferViews"] = Value::Array(std::mem::take(&mut w.views));
        root["accessors"] = Value::Array(std::mem::take(&mut w.accessors));
    }
    w.pad();
    Ok((root, w.bin))
}

/// Encodes linear texels as an 8-bit sRGB PNG.
fn encode_png(tex: &Texture) -> Result<Vec<u8>, String> {
    let bytes: Vec<u8> = tex
        .texels
        .iter()
        .flat_map(|c| {
            c.to_array()
                .map(|x| (linear_to_srgb(x) * 255.0).round() as u8)
        })
        .collect();
    let img = image::RgbImage::from_raw(tex.width, tex.height, bytes).ok_or_else(|| {
        format!(
            "{} texels for {}x{}",
            tex.texels.len(),
            tex.width,
            tex.height
        )
    })?;
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png)
        .map_err(|e| e.to_string())?;
    Ok(out.into_inner())
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};

    use super::*;

    /// A unique path in the temporary directory.
    fn temp_file(name: &str) -> std::path::PathBuf {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        std::env::temp_dir().join(format!(
            "scene_core_gltf_io_{}_{n}_{name}",
            std::process::id()
        ))
    }

    fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
        (a - b).abs().max_element() <= tol * a.abs().max_element().max(1.0)
    }

    #[track_caller]
    fn assert_close(a: Vec3, b: Vec3, tol: f32, what: &str) {
        assert!(close(a, b, tol), "{what}: {a} vs {b}");
    }

    /// Two meshes with material runs 0,0,1,1,0,0 / 2,3; a textured, an emissive (> 1) and a
    /// dim emissive material; point lights with and without radius; a sun; two cameras.
    fn test_scene() -> Scene {
        let mut s = Scene::new("test");
        s.materials = vec![
            Material::diffuse("white", Vec3::new(0.7, 0.7, 0.7)),
            Material {
                albedo_texture: Some(0),
                ..Material::diffuse("checker", Vec3::new(0.9, 0.8, 0.5))
            },
            Material::emissive("lamp", Vec3::splat(0.78), Vec3::new(17.0, 12.0, 4.0)),
            Material::emissive("dim", Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.5, 0.25, 0.0)),
        ];
        s.textures = vec![Texture {
            name: "checker".into(),
            width: 2,
            height: 2,
            texels: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 1.0),
                Vec3::new(0.2, 0.4, 0.6),
                Vec3::new(0.05, 0.5, 0.9),
            ],
        }];
        let mut room = Mesh {
            name: "room".into(),
            uvs: Some(Vec::new()),
            ..Default::default()
        };
        let q = |x: f32| {
            [
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + 1.0, 0.0, 0.0),
                Vec3::new(x + 1.0, 1.0, 0.5),
                Vec3::new(x, 1.0, 0.5),
            ]
        };
        room.push_quad(q(0.0), 0);
        room.push_quad(q(1.0), 1);
        room.push_quad(q(2.0), 0);
        // Unnamed: names must survive the round trip even when empty.
        let mut lamp = Mesh::default();
        lamp.push_triangle(
            [
                Vec3::new(0.0, 2.0, 0.0),
                Vec3::new(0.0, 2.0, 1.0),
                Vec3::new(1.0, 2.0, 0.0),
            ],
            2,
        );
        lamp.push_triangle(
            [
                Vec3::new(0.0, 3.0, 0.0),
                Vec3::new(1.0, 3.0, 1.0),
                Vec3::new(1.0, 3.0, 0.0),
            ],
            3,
        );
        s.meshes = vec![room, lamp];
        s.point_lights = vec![
            PointLight {
                name: "bulb".into(),
                position: Vec3::new(0.5, 1.5, 0.5),
                intensity: Vec3::new(3.0, 2.0, 1.0),
                radius: Some(4.0),
            },
            PointLight {
                name: "candle".into(),
                position: Vec3::new(-1.0, 0.25, 2.0),
                intensity: Vec3::new(0.5, 0.5, 0.25),
                radius: None,
            },
        ];
        s.directional_lights = vec![DirectionalLight {
            name: "sun".into(),
            direction: Vec3::new(0.3, -1.0, 0.2).normalize(),
            irradiance: Vec3::new(2.0, 1.9, 1.7),
        }];
        s.cameras = vec![
            Camera {
                name: "main".into(),
                position: Vec3::new(1.5, 0.5, 4.0),
                target: Vec3::new(1.5, 0.5, 0.0),
                up: Vec3::Y,
                fov_y: 0.7,
                aspect: 1.5,
                near: 0.05,
                far: 40.0,
            },
            Camera {
                name: "top".into(),
                position: Vec3::new(1.0, 6.0, 1.0),
                target: Vec3::new(1.2, 0.0, 0.9),
                up: Vec3::Z,
                fov_y: 1.1,
                aspect: 0.75,
                near: 0.1,
                far: 20.0,
            },
        ];
        s.validate().expect("test scene is valid");
        s
    }

    /// Same triangles (positions, normals, UVs of textured triangles), materials, textures,
    /// lights and cameras.
    #[track_caller]
    fn assert_round_trip(a: &Scene, b: &Scene) {
        assert_eq!(a.meshes.len(), b.meshes.len(), "mesh count");
        for (ma, mb) in a.meshes.iter().zip(&b.meshes) {
            assert_eq!(ma.name, mb.name);
            assert_eq!(
                ma.indices.len(),
                mb.indices.len(),
                "{}: triangle count",
                ma.name
            );
            assert_eq!(
                ma.material_ids, mb.material_ids,
                "{}: material ids",
                ma.name
            );
            for (t, (ta, tb)) in ma.indices.iter().zip(&mb.indices).enumerate() {
                let textured = a.materials[ma.material_ids[t] as usize]
                    .albedo_texture
                    .is_some();
                for k in 0..3 {
                    let (va, vb) = (ta[k] as usize, tb[k] as usize);
                    let what = format!("{} triangle {t} corner {k}", ma.name);
                    assert_close(ma.positions[va], mb.positions[vb], 1e-5, &what);
                    assert_close(ma.normals[va], mb.normals[vb], 1e-5, &what);
                    if textured {
                        let (ua, ub) = (ma.uvs.as_ref().unwrap()[va], mb.uvs.as_ref().unwrap()[vb]);
                        assert!(
                            (ua - ub).abs().max_element() < 1e-6,
                            "{what}: uv {ua} vs {ub}"
                        );
                    }
                }
            }
        }
        assert_eq!(a.materials.len(), b.materials.len(), "material count");
        for (x, y) in a.materials.iter().zip(&b.materials) {
            assert_eq!(x.name, y.name);
            assert_close(x.albedo, y.albedo, 1e-5, &x.name);
            assert_close(x.emission, y.emission, 1e-5, &x.name);
            assert_eq!(x.albedo_texture, y.albedo_texture, "{}", x.name);
        }
        assert_eq!(a.textures.len(), b.textures.len(), "texture count");
        for (x, y) in a.textures.iter().zip(&b.textures) {
            assert_eq!((&x.name, x.width, x.height), (&y.name, y.width, y.height));
            for (p, q) in x.texels.iter().zip(&y.texels) {
                // 8-bit sRGB quantisation.
                assert!((*p - *q).abs().max_element() < 6e-3, "texel {p} vs {q}");
            }
        }
        assert_eq!(a.point_lights.len(), b.point_lights.len());
        for (x, y) in a.point_lights.iter().zip(&b.point_lights) {
            assert_eq!(x.name, y.name);
            assert_close(x.position, y.position, 1e-5, &x.name);
            assert_close(x.intensity, y.intensity, 1e-5, &x.name);
            assert_eq!(x.radius, y.radius);
        }
        assert_eq!(a.directional_lights.len(), b.directional_lights.len());
        for (x, y) in a.directional_lights.iter().zip(&b.directional_lights) {
            assert_eq!(x.name, y.name);
            assert_close(x.direction, y.direction, 1e-5, &x.name);
            assert_close(x.irradiance, y.irradiance, 1e-5, &x.name);
        }
        assert_eq!(a.cameras.len(), b.cameras.len());
        for (x, y) in a.cameras.iter().zip(&b.cameras) {
            assert_eq!(x.name, y.name);
            assert_close(x.position, y.position, 1e-5, &x.name);
            let (da, db) = (x.target - x.position, y.target - y.position);
            assert_close(da.normalize(), db.normalize(), 1e-5, &x.name);
            assert!((da.length() - db.length()).abs() <= 1e-5 * da.length().max(1.0));
            // The up vector may be re-orthogonalised but must keep its side.
            assert!(x.up.normalize().dot(y.up) > 0.0 && db.cross(y.up).length() > 1e-3);
            assert!((x.fov_y - y.fov_y).abs() < 1e-5);
            assert!((x.aspect - y.aspect).abs() < 1e-5);
            assert!((x.near - y.near).abs() < 1e-5 * x.near.max(1.0));
            assert!((x.far - y.far).abs() < 1e-5 * x.far.max(1.0));
        }
    }

    fn export_bytes(scene: &Scene, ext: &str) -> Vec<u8> {
        let path = temp_file(&format!("bytes.{ext}"));
        export(scene, &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        bytes
    }

    fn round_trip_file(scene: &Scene, ext: &str) -> ImportResult {
        let path = temp_file(&format!("round_trip.{ext}"));
        export(scene, &path).unwrap();
        let result = import(&path);
        std::fs::remove_file(&path).unwrap();
        result.unwrap()
    }

    #[test]
    fn round_trip_gltf() {
        let s = test_scene();
        let r = round_trip_file(&s, "gltf");
        assert_round_trip(&s, &r.scene);
        assert!(r.ignored.is_empty(), "{:?}", r.ignored);
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        assert_eq!(r.summary(), "ignored: nothing");
    }

    #[test]
    fn round_trip_glb_file_and_slice() {
        let s = test_scene();
        let r = round_trip_file(&s, "GLB");
        assert_round_trip(&s, &r.scene);
        assert!(r.ignored.is_empty() && r.warnings.is_empty(), "{r:?}");
        let bytes = export_bytes(&s, "glb");
        assert!(bytes.starts_with(b"glTF"));
        let r = import_slice(&bytes, Path::new("mem.glb")).unwrap();
        assert_eq!(r.scene.name, "mem");
        assert_round_trip(&s, &r.scene);
    }

    #[test]
    fn export_layout_is_spec_shaped() {
        let s = test_scene();
        let bytes = export_bytes(&s, "gltf");
        let root: Value = serde_json::from_slice(&bytes).unwrap();
        assert_eq!(root["asset"]["version"], "2.0");
        let used: Vec<&str> = root["extensionsUsed"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        assert_eq!(used, [EXT_LIGHTS, EXT_EMISSIVE_STRENGTH]);
        // One primitive per contiguous material run: 0,0 | 1,1 | 0,0 and 2 | 3.
        let prims = |m: usize| root["meshes"][m]["primitives"].as_array().unwrap().clone();
        let mats: Vec<u64> = prims(0)
            .iter()
            .map(|p| p["material"].as_u64().unwrap())
            .collect();
        assert_eq!(mats, [0, 1, 0]);
        assert_eq!(prims(1).len(), 2);
        for p in prims(0) {
            let pos = &root["accessors"][p["attributes"]["POSITION"].as_u64().unwrap() as usize];
            assert!(pos["min"].is_array() && pos["max"].is_array());
            assert!(p["attributes"]["TEXCOORD_0"].is_u64());
            let idx = &root["accessors"][p["indices"].as_u64().unwrap() as usize];
            assert_eq!(idx["componentType"], GL_UNSIGNED_INT);
            let view = &root["bufferViews"][idx["bufferView"].as_u64().unwrap() as usize];
            assert_eq!(view["target"], GL_ELEMENT_ARRAY_BUFFER);
        }
        assert!(
            root["buffers"][0]["uri"]
                .as_str()
                .unwrap()
                .starts_with("data:application/octet-stream;base64,")
        );
        let lamp = &root["materials"][2];
        assert_eq!(
            lamp["extensions"][EXT_EMISSIVE_STRENGTH]["emissiveStrength"],
            17.0
        );
        assert_eq!(lamp["emissiveFactor"][0], 1.0);
        assert!(root["materials"][3]["extensions"].is_null());
        // A file that gltf itself accepts (it validates the JSON).
        assert!(gltf::Gltf::from_slice(&bytes).is_ok());
    }

    #[test]
    fn export_rejects_invalid_scenes_and_unknown_extensions() {
        let mut s = test_scene();
        let path = temp_file("bad.obj");
        assert!(matches!(export(&s, &path), Err(GltfError::Write { .. })));
        assert!(!path.exists());
        s.materials[0].albedo = Vec3::ONE;
        let path = temp_file("bad.gltf");
        match export(&s, &path) {
            Err(GltfError::Invalid { path: p, source }) => {
                assert_eq!(p, path);
                assert!(matches!(source, crate::SceneError::AlbedoOutOfRange { .. }));
            }
            other => panic!("expected Invalid, got {other:?}"),
        }
        assert!(!path.exists());
    }

    #[test]
    fn round_trip_builtins() {
        for name in crate::builtin::SMALL_INSTANCES {
            let s = crate::builtin::scene(name).unwrap();
            for ext in ["gltf", "glb"] {
                let r = round_trip_file(&s, ext);
                assert_round_trip(&s, &r.scene);
                assert!(r.warnings.is_empty(), "{name}: {:?}", r.warnings);
            }
        }
    }

    /// A self-contained .gltf with one mesh (one primitive of `mode`), node 0 showing it in
    /// scene 0; `edit` adjusts the JSON before it is serialised.
    fn doc(
        positions: &[[f32; 3]],
        normals: Option<&[[f32; 3]]>,
        indices: Option<&[u32]>,
        mode: u32,
        edit: impl FnOnce(&mut Value),
    ) -> Vec<u8> {
        let mut w = BinWriter::default();
        let pos: Vec<Vec3> = positions.iter().map(|&p| Vec3::from(p)).collect();
        let mut attributes = json!({ "POSITION": w.vec3(&pos, true) });
        if let Some(n) = normals {
            let n: Vec<Vec3> = n.iter().map(|&p| Vec3::from(p)).collect();
            attributes["NORMAL"] = json!(w.vec3(&n, false));
        }
        let mut prim = json!({ "attributes": attributes, "mode": mode });
        if let Some(i) = indices {
            prim["indices"] = json!(w.indices(i));
        }
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&w.bin)
        );
        let mut root = json!({
            "asset": { "version": "2.0" },
            "scene": 0,
            "scenes": [{ "nodes": [0] }],
            "nodes": [{ "mesh": 0, "name": "tri" }],
            "meshes": [{ "primitives": [prim] }],
            "buffers": [{ "byteLength": w.bin.len(), "uri": uri }],
            "bufferViews": w.views,
            "accessors": w.accessors,
        });
        edit(&mut root);
        serde_json::to_vec(&root).unwrap()
    }

    const TRI: [[f32; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    const TRI_N: [[f32; 3]; 3] = [[0.577_350_26; 3]; 3];

    fn face_normal(m: &Mesh, t: usize) -> Vec3 {
        let [a, b, c] = m.indices[t].map(|i| m.positions[i as usize]);
        (b - a).cross(c - a).normalize()
    }

    #[test]
    fn node_hierarchy_is_flattened() {
        let s45 = std::f32::consts::FRAC_1_SQRT_2;
        let (sy, cy) = (15f32.to_radians().sin(), 15f32.to_radians().cos());
        let bytes = doc(&TRI, Some(&TRI_N), None, 4, |root| {
            root["nodes"] = json!([
                { "name": "parent", "translation": [10, 0, 0], "scale": [2, 2, 2], "children": [1] },
                { "name": "child", "mesh": 0, "translation": [0, 1, 0], "rotation": [0, 0, s45, s45] },
                { "name": "mirror", "mesh": 0, "scale": [-1, 1, 1] },
                { "name": "skew", "mesh": 0, "scale": [3, 1, 1], "rotation": [0, sy, 0, cy] },
                { "name": "matrix", "mesh": 0,
                  "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 5, 1] },
            ]);
            root["scenes"] = json!([{ "nodes": [0, 2, 3, 4] }]);
        });
        let r = import_slice(&bytes, Path::new("hierarchy.gltf")).unwrap();
        let m = &r.scene.meshes;
        let names: Vec<&str> = m.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["child", "mirror", "skew", "matrix"]);

        // parent(T(10,0,0) S(2)) * child(T(0,1,0) Rz(90)).
        let child = &m[0];
        let expected = [
            Vec3::new(10.0, 4.0, 0.0),
            Vec3::new(8.0, 2.0, 0.0),
            Vec3::new(10.0, 2.0, 2.0),
        ];
        for (p, e) in child.positions.iter().zip(expected) {
            assert_close(*p, e, 1e-5, "child position");
        }
        assert_close(
            child.normals[0],
            Vec3::new(-1.0, 1.0, 1.0).normalize(),
            1e-5,
            "child normal",
        );
        assert_eq!(child.indices, [[0, 1, 2]]);

        // Mirror: positions mirrored, normal by the inverse transpose, winding flipped.
        let mirror = &m[1];
        assert_close(
            mirror.positions[0],
            Vec3::new(-1.0, 0.0, 0.0),
            1e-6,
            "mirror",
        );
        assert_close(
            mirror.normals[0],
            Vec3::new(-1.0, 1.0, 1.0).normalize(),
            1e-5,
            "mirror normal",
        );
        assert_eq!(mirror.indices, [[0, 2, 1]]);
        assert!(face_normal(mirror, 0).dot(mirror.normals[0]) > 0.99);

        // Non-uniform scale: the normal stays perpendicular to the surface and unit length.
        let skew = &m[2];
        let n = skew.normals[0];
        assert!((n.length() - 1.0).abs() < 1e-5);
        assert!(
            (face_normal(skew, 0).dot(n) - 1.0).abs() < 1e-5,
            "skew normal {n}"
        );
        let [a, b, c] = [0, 1, 2].map(|i| skew.positions[i]);
        assert_close(
            a,
            Quat::from_rotation_y(30f32.to_radians()) * Vec3::new(3.0, 0.0, 0.0),
            1e-5,
            "skew",
        );
        assert!((b - a).dot(n).abs() < 1e-5 && (c - a).dot(n).abs() < 1e-5);

        assert_close(m[3].positions[0], Vec3::new(1.0, 0.0, 5.0), 1e-6, "matrix");
    }

    #[test]
    fn emissive_strength_multiplies_and_default_albedo_is_clamped() {
        let bytes = doc(&TRI, Some(&TRI_N), None, 4, |root| {
            root["materials"] = json!([{
                "name": "glow",
                "emissiveFactor": [1.0, 0.5, 0.25],
                "extensions": { EXT_EMISSIVE_STRENGTH: { "emissiveStrength": 4.0 } },
            }]);
            root["meshes"][0]["primitives"][0]["material"] = json!(0);
            root["extensionsUsed"] = json!([EXT_EMISSIVE_STRENGTH]);
        });
        let r = import_slice(&bytes, Path::new("glow.gltf")).unwrap();
        let m = &r.scene.materials[0];
        assert_eq!(m.emission, Vec3::new(4.0, 2.0, 1.0));
        assert_eq!(m.albedo, Vec3::splat(ALBEDO_MAX));
        assert!(
            r.warnings
                .iter()
                .any(|w| w.contains("'glow'") && w.contains("albedo clamped below 1"))
        );
        // glTF's default metallicFactor is 1.
        assert_eq!(r.summary(), "ignored: 1 metallic/roughness setting");
    }

    #[test]
    fn lights_and_cameras_from_nodes() {
        // Half of a -45 degree turn about X: -Z turns to (0, -1, -1) / sqrt 2.
        let (s, c) = ((-22.5f32).to_radians().sin(), (-22.5f32).to_radians().cos());
        let bytes = doc(&TRI, Some(&TRI_N), None, 4, |root| {
            root["extensionsUsed"] = json!([EXT_LIGHTS, "KHR_texture_transform"]);
            root["extensions"] = json!({ EXT_LIGHTS: { "lights": [
                { "name": "cone", "type": "spot", "color": [1.0, 0.5, 0.5], "intensity": 10.0,
                  "range": 5.0, "spot": { "outerConeAngle": 0.5 } },
                { "name": "sun", "type": "directional", "intensity": 3.0 },
                { "type": "point", "color": [0.0, 1.0, 0.0], "intensity": 2.0 },
            ]}});
            root["cameras"] = json!([
                { "name": "persp", "type": "perspective", "perspective": { "yfov": 0.8, "znear": 0.1 } },
                { "type": "orthographic", "orthographic": { "xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 10 } },
            ]);
            root["nodes"] = json!([
                { "mesh": 0 },
                { "translation": [1, 2, 3], "rotation": [0.3, 0.2, 0.1, 0.927],
                  "extensions": { EXT_LIGHTS: { "light": 0 } } },
                { "rotation": [s, 0, 0, c], "translation": [5, 5, 5],
                  "extensions": { EXT_LIGHTS: { "light": 1 } } },
                { "translation": [0, 0, 1], "children": [4] },
                { "translation": [0, 1, 0], "extensions": { EXT_LIGHTS: { "light": 2 } } },
                { "camera": 0, "translation": [0, 1, 5] },
                { "camera": 1 },
            ]);
            root["scenes"] =
                json!([{ "nodes": [0, 1, 2, 3, 5, 6] }, { "name": "unused", "nodes": [] }]);
            root["animations"] = json!([]);
        });
        let r = import_slice(&bytes, Path::new("lights.gltf")).unwrap();
        let sc = &r.scene;
        assert_eq!(sc.point_lights.len(), 2);
        let cone = &sc.point_lights[0];
        assert_eq!(cone.name, "cone");
        assert_close(
            cone.position,
            Vec3::new(1.0, 2.0, 3.0),
            1e-6,
            "spot position",
        );
        assert_eq!(cone.intensity, Vec3::new(10.0, 5.0, 5.0));
        assert_eq!(cone.radius, Some(5.0));
        assert!(
            r.warnings
                .iter()
                .any(|w| w.contains("'cone'") && w.contains("spot"))
        );
        let green = &sc.point_lights[1];
        assert_close(
            green.position,
            Vec3::new(0.0, 1.0, 1.0),
            1e-6,
            "nested light",
        );
        assert_eq!(
            (green.intensity, green.radius),
            (Vec3::new(0.0, 2.0, 0.0), None)
        );

        let sun = &sc.directional_lights[0];
        assert_close(
            sun.direction,
            Vec3::new(0.0, -1.0, -1.0).normalize(),
            1e-5,
            "sun",
        );
        assert_eq!(sun.irradiance, Vec3::splat(3.0));

        assert_eq!(sc.cameras.len(), 1);
        let cam = &sc.cameras[0];
        assert_eq!(cam.name, "persp");
        assert_eq!(cam.position, Vec3::new(0.0, 1.0, 5.0));
        assert_close(
            (cam.target - cam.position).normalize(),
            Vec3::NEG_Z,
            1e-6,
            "view",
        );
        assert_close(cam.up, Vec3::Y, 1e-6, "up");
        assert_eq!((cam.fov_y, cam.aspect, cam.near), (0.8, 1.0, 0.1));
        assert!(cam.far >= 100.0 && cam.far.is_finite(), "far {}", cam.far);

        assert_eq!(
            r.summary(),
            "ignored: 1 extension, 1 other scene, 1 spot cone (imported as point light), \
             1 orthographic camera"
        );
        assert!(
            r.ignored
                .contains(&"extension: KHR_texture_transform".to_string())
        );
    }

    #[test]
    fn strips_fans_lines_and_default_material() {
        let quad = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
        ];
        // Strip without indices: sequential indices, odd triangles reversed.
        let r = import_slice(&doc(&quad, None, None, 5, |_| {}), Path::new("strip.gltf")).unwrap();
        let m = &r.scene.meshes[0];
        assert_eq!(m.indices, [[0, 1, 2], [1, 3, 2]]);
        assert!(
            m.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6),
            "recomputed normals"
        );
        assert_eq!(r.scene.materials.len(), 1);
        assert_eq!(r.scene.materials[0].name, DEFAULT_MATERIAL_NAME);
        assert_eq!(r.scene.materials[0].albedo, Vec3::splat(DEFAULT_ALBEDO));
        assert_eq!(m.material_ids, [0, 0]);

        let r = import_slice(
            &doc(&quad, None, Some(&[0, 1, 3, 2]), 6, |_| {}),
            Path::new("fan.gltf"),
        )
        .unwrap();
        assert_eq!(r.scene.meshes[0].indices, [[1, 3, 0], [3, 2, 0]]);

        // Lines are skipped and listed, not an error.
        let lines = doc(&quad, None, Some(&[0, 1, 1, 2]), 1, |root| {
            let tri = root["meshes"][0]["primitives"][0].clone();
            let mut tri = tri;
            tri["mode"] = json!(4);
            tri.as_object_mut().unwrap().remove("indices");
            root["meshes"][0]["primitives"]
                .as_array_mut()
                .unwrap()
                .push(tri);
        });
        let r = import_slice(&lines, Path::new("lines.gltf")).unwrap();
        assert_eq!(r.scene.meshes[0].indices.len(), 1);
        assert_eq!(r.summary(), "ignored: 1 point/line primitive");
        assert!(r.ignored[0].contains("primitive 0"), "{:?}", r.ignored);
    }

    #[test]
    fn summary_groups_and_pluralises() {
        let r = ImportResult {
            scene: Scene::default(),
            ignored: vec![
                "metallic-roughness texture: a".into(),
                "spot cone (imported as point light): s".into(),
                "metallic-roughness texture: b".into(),
                "animation: x".into(),
                "metallic-roughness texture: c".into(),
                "animation: y".into(),
            ],
            warnings: vec![],
        };
        assert_eq!(
            r.summary(),
            "ignored: 3 metallic-roughness textures, 1 spot cone (imported as point light), \
             2 animations"
        );
    }

    #[test]
    fn missing_file_is_a_read_error_naming_the_path() {
        let path = temp_file("does_not_exist.glb");
        match import(&path) {
            Err(GltfError::Read { path: p, message }) => {
                assert_eq!(p, path);
                assert!(!message.is_empty());
            }
            other => panic!("expected Read, got {other:?}"),
        }
    }

    #[track_caller]
    fn assert_read_err(bytes: &[u8], what: &str) {
        match import_slice(bytes, Path::new("corrupt.gltf")) {
            Err(GltfError::Read { path, .. }) => assert_eq!(path, Path::new("corrupt.gltf")),
            other => panic!("{what}: expected Read error, got {other:?}"),
        }
    }

    #[test]
    fn truncated_and_corrupted_files_are_errors() {
        let s = test_scene();
        for ext in ["gltf", "glb"] {
            let bytes = export_bytes(&s, ext);
            for frac in [0.1, 0.5, 0.9] {
                let cut = (bytes.len() as f64 * frac) as usize;
                assert_read_err(&bytes[..cut], &format!("{ext} cut at {frac}"));
            }
            // Every shorter length fails too (sampled).
            for cut in (0..bytes.len()).step_by(97) {
                assert!(
                    import_slice(&bytes[..cut], Path::new("x")).is_err(),
                    "{ext} cut {cut}"
                );
            }
        }
        // Bytes flipped in the middle of a .gltf (JSON or base64 text) are never valid.
        let gltf = export_bytes(&s, "gltf");
        let mut flipped = gltf.clone();
        let mid = flipped.len() / 2;
        for b in &mut flipped[mid..mid + 4] {
            *b ^= 0xFF;
        }
        assert_read_err(&flipped, "gltf flipped");
        // In a .glb, flipping bytes of the JSON chunk is detected.
        let glb = export_bytes(&s, "glb");
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        let mut flipped = glb.clone();
        let mid = 20 + json_len / 2;
        for b in &mut flipped[mid..mid + 4] {
            *b ^= 0xFF;
        }
        assert_read_err(&flipped, "glb JSON flipped");
        // A GLB header length below the header size (gltf 1.4 would underflow).
        let mut short = glb.clone();
        short[8..12].copy_from_slice(&4u32.to_le_bytes());
        assert_read_err(&short, "glb length 4");
        // Not JSON at all.
        assert_read_err(b"{ \"asset\": { \"version\": \"2.0\" ", "unterminated JSON");
        assert_read_err(b"\x00\x01garbage", "garbage");
        assert_read_err(b"", "empty");
    }

    #[test]
    fn flipping_any_byte_never_panics() {
        let s = test_scene();
        for ext in ["glb", "gltf"] {
            let bytes = export_bytes(&s, ext);
            let step = (bytes.len() / 400).max(1);
            for i in (0..bytes.len()).step_by(step) {
                for mask in [0xFF, 0x01, 0x80] {
                    let mut b = bytes.clone();
                    b[i] ^= mask;
                    // Binary payload flips may still import; they must not panic.
                    let _ = import_slice(&b, Path::new("fuzz"));
                }
            }
        }
    }

    /// Edits the JSON of the exported test scene and imports it.
    fn import_edited(edit: impl FnOnce(&mut Value)) -> Result<ImportResult, GltfError> {
        let bytes = export_bytes(&test_scene(), "gltf");
        let mut root: Value = serde_json::from_slice(&bytes).unwrap();
        edit(&mut root);
        import_slice(
            &serde_json::to_vec(&root).unwrap(),
            Path::new("edited.gltf"),
        )
    }

    #[test]
    fn out_of_range_references_are_errors() {
        type Edit = fn(&mut Value);
        let read_errors: [(&str, Edit); 9] = [
            ("POSITION accessor index", |r| {
                r["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(999)
            }),
            ("NORMAL accessor index", |r| {
                r["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(999)
            }),
            ("indices accessor index", |r| {
                r["meshes"][0]["primitives"][0]["indices"] = json!(999)
            }),
            ("material index", |r| {
                r["meshes"][0]["primitives"][0]["material"] = json!(99)
            }),
            ("node mesh index", |r| r["nodes"][0]["mesh"] = json!(99)),
            ("huge accessor count", |r| {
                r["accessors"][0]["count"] = json!(1u64 << 40)
            }),
            ("view past buffer", |r| {
                r["bufferViews"][0]["byteOffset"] = json!(1u64 << 20)
            }),
            ("accessor offset past view", |r| {
                r["accessors"][0]["byteOffset"] = json!(4096)
            }),
            ("image without mime type", |r| {
                r["images"][0].as_object_mut().unwrap().remove("mimeType");
            }),
        ];
        for (what, edit) in read_errors {
            match import_edited(edit) {
                Err(GltfError::Read { message, .. }) => assert!(!message.is_empty()),
                other => panic!("{what}: expected Read error, got {other:?}"),
            }
        }
        let content_errors: [(&str, Edit); 3] = [
            ("POSITION is VEC2", |r| {
                r["accessors"][0]["type"] = json!("VEC2")
            }),
            ("accessor count 0", |r| {
                r["accessors"][0]["count"] = json!(0)
            }),
            ("node cycle", |r| {
                r["nodes"][0]["children"] = json!([1]);
                r["nodes"][1]["children"] = json!([0]);
            }),
        ];
        for (what, edit) in content_errors {
            match import_edited(edit) {
                Err(GltfError::Content { .. }) => {}
                other => panic!("{what}: expected Content error, got {other:?}"),
            }
        }
        // Percent-encoded URIs that are not UTF-8 (gltf 1.4 would panic decoding them).
        let r = import_edited(|r| r["buffers"][0]["uri"] = json!("%FF%FE.bin"));
        assert!(matches!(r, Err(GltfError::RefusedUri { .. })), "{r:?}");
    }

    #[test]
    fn index_past_vertex_count_is_a_content_error_naming_the_primitive() {
        let bytes = doc(&TRI, None, Some(&[0, 1, 3]), 4, |_| {});
        match import_slice(&bytes, Path::new("idx.gltf")) {
            Err(GltfError::Content { message, .. }) => {
                assert!(
                    message.contains("primitive 0") && message.contains("index 3"),
                    "{message}"
                );
            }
            other => panic!("expected Content error, got {other:?}"),
        }
    }

    #[test]
    fn invalid_scene_is_reported() {
        let bytes = doc(&TRI, None, None, 4, |root| {
            root["materials"] = json!([{ "emissiveFactor": [1.0, 1.0, 1.0],
                "extensions": { EXT_EMISSIVE_STRENGTH: { "emissiveStrength": -2.0 } } }]);
            root["meshes"][0]["primitives"][0]["material"] = json!(0);
        });
        match import_slice(&bytes, Path::new("neg.gltf")) {
            Err(GltfError::Invalid { source, .. }) => {
                assert!(matches!(source, crate::SceneError::InvalidEmission { .. }));
            }
            other => panic!("expected Invalid, got {other:?}"),
        }
    }
}
