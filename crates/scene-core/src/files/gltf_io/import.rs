//! glTF import: the file and everything it names, read under a budget and a URI policy,
//! flattened into a validated [`Scene`] (see the [parent module](super)).

use std::borrow::Cow;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use glam::{Mat3, Mat4, Vec2, Vec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::khr_lights_punctual::Kind as LightKind;
use gltf::mesh::Mode;
use serde_json::Value;

use super::uri::{self, ExternalFiles};
use super::{
    ALBEDO_MAX, DEFAULT_ALBEDO, DEFAULT_MATERIAL_NAME, EXT_EMISSIVE_STRENGTH, EXT_LIGHTS,
    EXT_TEXTURE_TRANSFORM, TARGET_DISTANCE_KEY,
};
use crate::budget::{Allowance, Budget};
use crate::error::{GltfError, ImageError};
use crate::image::Image;
use crate::scene::{
    Camera, DirectionalLight, Material, Mesh, PointLight, Sampler, Scene, Texture, Wrap,
    label_or_index,
};

/// What [`import`] produced: the scene plus what was left out and what was adjusted.
#[derive(Clone, Debug)]
pub struct ImportResult {
    /// The validated scene (named after the file stem).
    pub scene: Scene,
    /// Features of the file that were not imported, one entry each, as `"<kind>: <detail>"`
    /// (for example `"animation: 'Walk'"`).
    pub ignored: Vec<String>,
    /// Adjustments made while importing (clamped albedo, dropped degenerate triangles,
    /// ...).
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
    /// `"ignored: 3 metallic-roughness textures, 1 orthographic camera, 2 animations"`, or
    /// `"ignored: nothing"`.
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
    Transparency,
    OrthographicCamera,
    Extension,
    OtherScene,
}

impl Ignored {
    const ALL: [Ignored; 13] = [
        Ignored::Animation,
        Ignored::Skin,
        Ignored::MorphTargets,
        Ignored::VertexColors,
        Ignored::NonTriangles,
        Ignored::MetallicRoughness,
        Ignored::MetallicRoughnessTexture,
        Ignored::NormalTexture,
        Ignored::OcclusionTexture,
        Ignored::Transparency,
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
            Ignored::Transparency => ("blended material", "blended materials"),
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

/// Imports a `.gltf` (with embedded or external buffers and images) or `.glb` file.
///
/// See the [module documentation](crate::gltf_io) for what is imported and what is ignored.
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
    for (mesh, n) in &report.duplicates_dropped {
        warnings.push(format!(
            "{mesh}: {n} triangles dropped that repeat an earlier triangle's positions \
             (coincident faces)"
        ));
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
    colors: Option<Vec<Vec3>>,
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
            if ext != EXT_LIGHTS && ext != EXT_EMISSIVE_STRENGTH && ext != EXT_TEXTURE_TRANSFORM {
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
            let world = parent * self.node_matrix(&node)?;
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
            if cam.far / cam.near > crate::scene::DEPTH_RANGE_MAX {
                let near = cam.far / crate::scene::DEPTH_RANGE_MAX;
                self.warnings.push(format!(
                    "{}: infinite projection with znear {:e}: the far plane is set to the \
                     scene's reach {:e} and near raised to {near:e} (far / near at most {:e})",
                    label_or_index(&cam.name, "camera", p.camera),
                    cam.near,
                    cam.far,
                    crate::scene::DEPTH_RANGE_MAX
                ));
                cam.near = near;
            }
        }
        Ok(())
    }

    /// A node's local matrix. glTF requires a unit rotation quaternion, and readers differ on
    /// what to make of another one: a zero or non-finite quaternion is refused naming the
    /// node; one whose length is off by more than 1e-3 is normalised with a warning.
    fn node_matrix(&mut self, node: &gltf::Node) -> Result<Mat4, GltfError> {
        match node.transform() {
            gltf::scene::Transform::Matrix { matrix } => Ok(Mat4::from_cols_array_2d(&matrix)),
            gltf::scene::Transform::Decomposed {
                translation,
                rotation,
                scale,
            } => {
                let q = glam::Quat::from_array(rotation);
                let len2 = q.length_squared();
                let label = label_or_index(node.name().unwrap_or(""), "node", node.index());
                if !(len2.is_finite() && len2 > 1e-12) {
                    return Err(content_error(
                        self.path,
                        format!(
                            "{label}: rotation {rotation:?} is not a unit quaternion (zero or \
                             not finite): its orientation is undefined"
                        ),
                    ));
                }
                if (len2 - 1.0).abs() > 1e-3 {
                    self.warnings.push(format!(
                        "{label}: rotation {rotation:?} is not a unit quaternion (length {:.4}); \
                         normalised",
                        len2.sqrt()
                    ));
                }
                Ok(Mat4::from_scale_rotation_translation(
                    Vec3::from(scale),
                    q.normalize(),
                    Vec3::from(translation),
                ))
            }
        }
    }

    fn import_materials(&mut self) -> Result<(), GltfError> {
        let doc = self.doc;
        // Textures used as base colour, decoded in glTF texture index order.
        let used: BTreeSet<usize> = doc
            .materials()
            .flat_map(|m| {
                [
                    m.pbr_metallic_roughness().base_color_texture(),
                    m.emissive_texture(),
                ]
            })
            .flatten()
            .map(|info| info.texture().index())
            .collect();
        // Textures whose alpha a masked (or blended, read as masked) material reads.
        let with_alpha: BTreeSet<usize> = doc
            .materials()
            .filter(|m| m.alpha_mode() != gltf::material::AlphaMode::Opaque)
            .filter_map(|m| m.pbr_metallic_roughness().base_color_texture())
            .map(|info| info.texture().index())
            .collect();
        let mut texture_map = BTreeMap::new();
        for t in used {
            let Some(texture) = doc.textures().nth(t) else {
                continue;
            };
            let decoded = self.decode_texture(&texture, with_alpha.contains(&t))?;
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
            let emission_texture = m
                .emissive_texture()
                .and_then(|info| texture_map.get(&info.texture().index()).copied());
            // glTF 3.9.4: the alpha is baseColorFactor.a times the texture's alpha; OPAQUE
            // ignores it, MASK keeps the surface where it reaches alphaCutoff (0.5 by
            // default). The factor is folded into the cutoff: alpha_tex >= cutoff / factor.
            // BLEND has no diffuse-transport meaning here: it is read as a mask at 0.5.
            let cutoff = match m.alpha_mode() {
                gltf::material::AlphaMode::Opaque => None,
                gltf::material::AlphaMode::Mask => Some(m.alpha_cutoff().unwrap_or(0.5)),
                gltf::material::AlphaMode::Blend => {
                    self.ignore(
                        Ignored::Transparency,
                        format!("{label} (read as a mask at 0.5)"),
                    );
                    Some(0.5)
                }
            };
            // glTF 5.19.3: alphaCutoff is at least 0. A negative (or non-finite) one is an
            // invalid material, not an opaque one.
            if let Some(c) = cutoff.filter(|c| !(c.is_finite() && *c >= 0.0)) {
                return Err(content_error(
                    self.path,
                    format!(
                        "{label}: alphaCutoff {c} is negative or not finite (glTF requires a \
                         value of at least 0): an invalid material"
                    ),
                ));
            }
            let alpha_cutoff = cutoff.map(|c| {
                // A factor of 0 (or a cutoff above it) leaves no surface: any value above 1.
                if c <= 0.0 {
                    0.0
                } else if f[3] > 0.0 {
                    (c / f[3]).min(2.0)
                } else {
                    2.0
                }
            });
            self.scene.materials.push(Material {
                name,
                albedo,
                albedo_texture,
                emission,
                emission_texture,
                alpha_cutoff,
            });
        }
        Ok(())
    }

    /// Decodes a base-colour texture, with its alpha channel when `with_alpha` (a masked
    /// material reads it) and the image has one.
    fn decode_texture(
        &mut self,
        texture: &gltf::Texture,
        with_alpha: bool,
    ) -> Result<Texture, GltfError> {
        use gltf::texture::{MagFilter, WrappingMode};
        let image = texture.source();
        let name = image
            .name()
            .or(texture.name())
            .map_or_else(|| format!("texture {}", texture.index()), str::to_string);
        // The sampler: wrap per axis, and nearest where the magnification filter says so
        // (textures have no mipmaps: the magnification filter decides every lookup).
        let gltf_sampler = texture.sampler();
        let wrap = |w: WrappingMode| match w {
            WrappingMode::Repeat => Wrap::Repeat,
            WrappingMode::ClampToEdge => Wrap::ClampToEdge,
            WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        };
        let sampler = Sampler {
            wrap_u: wrap(gltf_sampler.wrap_s()),
            wrap_v: wrap(gltf_sampler.wrap_t()),
            nearest: gltf_sampler.mag_filter() == Some(MagFilter::Nearest),
        };
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
        if with_alpha {
            self.allowance
                .charge_bytes(u64::from(w) * u64::from(h) * 4, || {
                    format!("{what}: {w}x{h} alpha values")
                })?;
        }
        let (decoded, alpha) =
            Image::decode_texture_with_alpha(&encoded, path, self.allowance.budget())
                .map_err(image_error)?;
        Ok(Texture {
            name,
            width: decoded.width,
            height: decoded.height,
            texels: decoded.pixels,
            alpha: alpha.filter(|_| with_alpha),
            sampler,
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
                    // A spot points along the node's world -Z (the extension's convention).
                    let cone = match kind {
                        LightKind::Spot {
                            inner_cone_angle,
                            outer_cone_angle,
                        } => Some(crate::lights::SpotCone {
                            direction: world.transform_vector3(Vec3::NEG_Z).normalize_or_zero(),
                            inner: inner_cone_angle,
                            outer: outer_cone_angle,
                        }),
                        _ => None,
                    };
                    self.scene.point_lights.push(PointLight {
                        name,
                        position: world.transform_point3(Vec3::ZERO),
                        intensity: power,
                        radius: light.range(),
                        cone,
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
            // Every primitive has normals by now (flat ones where the file has none). Zero
            // normals are recomputed by validation.
            let normals = data.normals.unwrap_or_default();
            out.normals.extend(normals.iter().map(|&n| {
                let n = (normal_matrix * n).normalize_or_zero();
                if n.is_finite() { n } else { Vec3::ZERO }
            }));
            out.normals.resize(total, Vec3::ZERO);
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
            match (data.colors, &mut out.colors) {
                (Some(c), Some(all)) => all.extend(c),
                (Some(c), None) => {
                    let mut all = vec![Vec3::ONE; base as usize];
                    all.extend(c);
                    out.colors = Some(all);
                }
                (None, Some(all)) => all.resize(total, Vec3::ONE),
                (None, None) => {}
            }
            out.indices.extend(data.triangles.iter().map(|t| {
                let [a, b, c] = t.map(|i| i + base);
                if flip { [a, c, b] } else { [a, b, c] }
            }));
            out.material_ids
                .extend(std::iter::repeat_n(data.material, data.triangles.len()));
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
        let material = match prim.material().index() {
            Some(m) => m as u32,
            None => self.default_material(),
        };
        // The base colour texture's coordinate set (KHR_texture_transform may name another)
        // and its transform, baked into the coordinates below; without a base colour
        // texture, the emissive texture's. The scene keeps one set of coordinates per
        // vertex: an emissive texture that reads other coordinates than the base colour's
        // reads the base colour's, with a warning.
        let emissive = prim.material().emissive_texture();
        let base_color = prim
            .material()
            .pbr_metallic_roughness()
            .base_color_texture();
        if let (Some(b), Some(e)) = (&base_color, &emissive) {
            let key = |i: &gltf::texture::Info| {
                let t = i.texture_transform();
                (
                    t.as_ref()
                        .and_then(|t| t.tex_coord())
                        .unwrap_or(i.tex_coord()),
                    t.map(|t| (t.offset(), t.rotation(), t.scale())),
                )
            };
            if key(b) != key(e) {
                self.warnings.push(format!(
                    "{at}: the emissive texture reads other texture coordinates than the base \
                     colour's; it reads the base colour's"
                ));
            }
        }
        let base_color = base_color.or(emissive);
        let transform = base_color
            .as_ref()
            .and_then(|info| info.texture_transform())
            .map(|t| UvTransform {
                offset: Vec2::from(t.offset()),
                rotation: t.rotation(),
                scale: Vec2::from(t.scale()),
                tex_coord: t.tex_coord(),
            });
        let tex_set = base_color.map(|info| {
            transform
                .and_then(|t| t.tex_coord)
                .unwrap_or_else(|| info.tex_coord())
        });

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
        // Without normals every triangle gets three vertices of its own (flat normals):
        // the file's vertices are read, then copied per corner.
        let has_normals = prim.get(&gltf::Semantic::Normals).is_some();
        let vertices = if has_normals {
            n
        } else {
            n.max(triangles.saturating_mul(3))
        };
        let read_vertices = if has_normals {
            n
        } else {
            n.saturating_add(triangles.saturating_mul(3))
        };
        // Bytes: the vertex arrays; the indices as read (4 each); per triangle its index
        // triple twice (primitive, then mesh) and its material id.
        self.allowance.charge_mesh(
            vertices,
            triangles.saturating_mul(3),
            read_vertices
                .saturating_mul(vertex_bytes)
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
                    Some(match transform {
                        Some(t) => uvs.into_iter().map(|uv| t.apply(uv)).collect(),
                        None => uvs,
                    })
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

        // COLOR_0 (linear RGB, or RGBA whose alpha is not read) multiplies the albedo.
        let colors = match prim.get(&gltf::Semantic::Colors(0)) {
            Some(acc) => {
                let dims = if acc.dimensions() == Dimensions::Vec4 {
                    Dimensions::Vec4
                } else {
                    Dimensions::Vec3
                };
                check(
                    &acc,
                    "COLOR_0",
                    &[DataType::F32, DataType::U8, DataType::U16],
                    dims,
                )?;
                same_count(&acc, "COLOR_0")?;
                let mut colors: Vec<Vec3> = reader
                    .read_colors(0)
                    .map(|it| it.into_rgb_f32().map(Vec3::from).collect())
                    .unwrap_or_default();
                if colors.len() != n {
                    return Err(count_mismatch("COLOR_0", colors.len(), n));
                }
                // A colour multiplies the albedo: NaN or infinity is bad data (refused), a
                // float outside [0, 1] (glTF's range) is clamped into it, and said.
                if let Some((v, c)) = colors.iter().enumerate().find(|(_, c)| !c.is_finite()) {
                    return Err(content_error(
                        path,
                        format!("{at}: COLOR_0 of vertex {v} is {c}, not finite"),
                    ));
                }
                let outside = colors
                    .iter()
                    .filter(|c| c.min_element() < 0.0 || c.max_element() > 1.0)
                    .count();
                if outside > 0 {
                    self.warnings.push(format!(
                        "{at}: COLOR_0 of {outside} of {n} vertices lies outside [0, 1]; \
                         clamped into it"
                    ));
                    for c in &mut colors {
                        *c = c.clamp(Vec3::ZERO, Vec3::ONE);
                    }
                }
                // glTF multiplies COLOR_0's alpha into a masked material's alpha; here only
                // the texture's alpha cuts holes, so a vertex alpha below 1 is reported.
                let masked = prim.material().alpha_mode() != gltf::material::AlphaMode::Opaque;
                if masked
                    && dims == Dimensions::Vec4
                    && reader
                        .read_colors(0)
                        .is_some_and(|it| it.into_rgba_f32().any(|c| c[3] < 1.0))
                {
                    self.ignore(
                        Ignored::VertexColors,
                        format!("{at} (COLOR_0's alpha on a masked material)"),
                    );
                }
                Some(colors)
            }
            None => None,
        };
        if prim.get(&gltf::Semantic::Colors(1)).is_some() {
            self.ignore(Ignored::VertexColors, format!("{at} (COLOR_1 and beyond)"));
        }

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
        let data = PrimitiveData {
            positions,
            normals,
            uvs,
            colors,
            triangles,
            material,
        };
        Ok(Some(if data.normals.is_some() {
            data
        } else {
            data.with_flat_normals()
        }))
    }
}

/// A texture's `KHR_texture_transform`: `uv' = R(rotation) (scale * uv) + offset`, with
/// `R` turning `(u, v)` into `(u cos + v sin, v cos - u sin)`: the extension's GLSL
/// matrices read row by row, as Cesium Native applies them.
#[derive(Clone, Copy, Debug, PartialEq)]
struct UvTransform {
    offset: Vec2,
    rotation: f32,
    scale: Vec2,
    /// The coordinate set it names instead of the texture info's, if any.
    tex_coord: Option<u32>,
}

impl UvTransform {
    fn apply(&self, uv: Vec2) -> Vec2 {
        let s = uv * self.scale;
        let (sin, cos) = self.rotation.sin_cos();
        Vec2::new(s.x * cos + s.y * sin, s.y * cos - s.x * sin) + self.offset
    }
}

impl PrimitiveData {
    /// Flat normals for a primitive without `NORMAL`, as glTF 2.0 asks of a client (3.7.2.1:
    /// "client implementations MUST calculate flat normals"): every triangle gets three
    /// vertices of its own carrying its face normal (in the primitive's space; the mesh
    /// builder transforms it as any normal). A degenerate triangle's normal is zero, which
    /// validation repairs or drops with the triangle.
    fn with_flat_normals(self) -> Self {
        let corners = self.triangles.len() * 3;
        let mut positions = Vec::with_capacity(corners);
        let mut normals = Vec::with_capacity(corners);
        let mut uvs = self.uvs.as_ref().map(|_| Vec::with_capacity(corners));
        let mut colors = self.colors.as_ref().map(|_| Vec::with_capacity(corners));
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| self.positions[i as usize]);
            let n = (b - a).cross(c - a).normalize_or_zero();
            for &i in t {
                positions.push(self.positions[i as usize]);
                normals.push(n);
                if let (Some(out), Some(src)) = (uvs.as_mut(), self.uvs.as_ref()) {
                    out.push(src[i as usize]);
                }
                if let (Some(out), Some(src)) = (colors.as_mut(), self.colors.as_ref()) {
                    out.push(src[i as usize]);
                }
            }
        }
        let triangles = (0..self.triangles.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        Self {
            positions,
            normals: Some(normals),
            uvs,
            colors,
            triangles,
            material: self.material,
        }
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
