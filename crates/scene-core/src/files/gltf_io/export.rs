//! glTF export: a [`Scene`] as `.gltf` (embedded buffer) or `.glb` (see the
//! [parent module](super)).

use std::borrow::Cow;
use std::collections::{BTreeMap, BTreeSet};
use std::io::Write as _;
use std::path::Path;

use base64::Engine as _;
use glam::{Mat3, Quat, Vec2, Vec3};
use serde_json::{Value, json};

use super::{EXT_EMISSIVE_STRENGTH, EXT_LIGHTS, TARGET_DISTANCE_KEY};
use crate::error::GltfError;
use crate::image::linear_to_srgb;
use crate::scene::{Scene, Texture};

pub(super) const GL_ARRAY_BUFFER: u32 = 34962;
pub(super) const GL_ELEMENT_ARRAY_BUFFER: u32 = 34963;
const GL_FLOAT: u32 = 5126;
pub(super) const GL_UNSIGNED_INT: u32 = 5125;
const GL_LINEAR: u32 = 9729;
const GL_REPEAT: u32 = 10497;
const GL_NEAREST: u32 = 9728;
const GL_CLAMP_TO_EDGE: u32 = 33071;
const GL_MIRRORED_REPEAT: u32 = 33648;

/// Stands in the JSON text for the embedded buffer's base64 while the text is written.
pub(super) const BUFFER_MARKER: &str = "@@scene-core-gltf-buffer-data@@";

/// Exports a scene as `.gltf` (JSON with the buffer embedded as a base64 data URI) or `.glb`,
/// chosen by the extension of `path` (case-insensitive).
///
/// The scene must pass [`Scene::validate`] (checked on a copy; the file is written from the
/// original, so triangle order and ids are kept) or [`GltfError::Invalid`] is returned. See
/// the [module documentation](crate::gltf_io) for the layout. I/O failures and an unknown extension
/// give [`GltfError::Write`]; a failed write leaves no partial file at `path`.
pub fn export(scene: &Scene, path: &Path) -> Result<(), GltfError> {
    export_with(scene, path, &[])
}

/// Extra per-vertex data to export with a mesh: `values[v]` for vertex `v` of
/// `scene.meshes[mesh]`, written as a float `VEC3` attribute `name` on each of the mesh's
/// primitives. `name` is `COLOR_0` (values in [0, 1], as the glTF specification requires
/// of colours) or an application-specific name starting with `_` (e.g. `_RADIOSITY_POINT_0`).
#[derive(Clone, Debug, PartialEq)]
pub struct VertexAttribute {
    /// The attribute's semantic name.
    pub name: String,
    /// The mesh it belongs to.
    pub mesh: usize,
    /// One value per vertex of that mesh.
    pub values: Vec<Vec3>,
}

/// [`export`] with extra per-vertex attributes. A name that is neither `COLOR_0` nor
/// `_`-prefixed, a mesh that does not exist, a value count that is not the mesh's vertex
/// count, a non-finite value or a `COLOR_0` value outside [0, 1] is a [`GltfError::Write`]
/// naming it, and nothing is written.
pub fn export_with(
    scene: &Scene,
    path: &Path,
    attributes: &[VertexAttribute],
) -> Result<(), GltfError> {
    for a in attributes {
        let fault = if a.name != "COLOR_0" && !(a.name.starts_with('_') && a.name.len() > 1) {
            Some("the name must be COLOR_0 or start with '_'".to_string())
        } else if let Some(mesh) = scene.meshes.get(a.mesh) {
            if a.values.len() != mesh.positions.len() {
                Some(format!(
                    "{} values for mesh {} with {} vertices",
                    a.values.len(),
                    a.mesh,
                    mesh.positions.len()
                ))
            } else if a.values.iter().any(|v| !v.is_finite()) {
                Some("a value is not finite".into())
            } else if a.name == "COLOR_0" && mesh.colors.is_some() {
                Some(format!(
                    "mesh {} has colours of its own (Mesh::colors)",
                    a.mesh
                ))
            } else if a.name == "COLOR_0"
                && a.values
                    .iter()
                    .any(|v| v.min_element() < 0.0 || v.max_element() > 1.0)
            {
                Some("a colour is outside [0, 1]".into())
            } else {
                None
            }
        } else {
            Some(format!("mesh {} does not exist", a.mesh))
        };
        if let Some(fault) = fault {
            return Err(write_error(
                path,
                format!("vertex attribute '{}': {fault}", a.name),
            ));
        }
    }
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
    let (mut root, bin) =
        build_document(scene, &checked, attributes).map_err(|m| write_error(path, m))?;
    // Written into the file as it is made (through a temporary one): the building's
    // relight export, an 84 MB buffer, held the buffer, its base64 text, a copy of that and
    // the whole JSON text at once (the relight job's peak, 420 MB above the solution).
    if binary {
        if !bin.is_empty() {
            root["buffers"] = json!([{ "byteLength": bin.len() }]);
        }
        let json_bytes = serde_json::to_vec(&root).map_err(|e| write_error(path, e))?;
        drop(root);
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
        write_atomically(path, |file| {
            glb.to_writer(file)
                .map_err(|e| std::io::Error::other(e.to_string()))
        })
    } else {
        // The JSON without the buffer's data is small: written around a marker where the
        // data URI's base64 goes, which is encoded from the buffer straight into the file
        // (a 112 MB buffer's text would otherwise be held twice over).
        let marker = BUFFER_MARKER;
        let prefix = "data:application/octet-stream;base64,";
        if !bin.is_empty() {
            root["buffers"] = json!([{ "byteLength": bin.len(), "uri": marker }]);
        }
        let text = serde_json::to_string_pretty(&root).map_err(|e| write_error(path, e))?;
        drop(root);
        // `"uri": "<marker>"` is the marker's only place unless a name in the scene holds
        // it: then the whole text is built in memory.
        let (head, tail) = match text.match_indices(marker).count() {
            1 if !bin.is_empty() => text.split_once(marker).unwrap_or((&text, "")),
            _ if !bin.is_empty() => {
                let mut root: Value =
                    serde_json::from_str(&text).map_err(|e| write_error(path, e))?;
                root["buffers"][0]["uri"] = Value::String(format!(
                    "{prefix}{}",
                    base64::engine::general_purpose::STANDARD.encode(&bin)
                ));
                let text = serde_json::to_string_pretty(&root).map_err(|e| write_error(path, e))?;
                return write_atomically(path, |file| file.write_all(text.as_bytes()));
            }
            _ => (text.as_str(), ""),
        };
        write_atomically(path, |file| {
            file.write_all(head.as_bytes())?;
            if !bin.is_empty() {
                file.write_all(prefix.as_bytes())?;
                let mut encoder = base64::write::EncoderWriter::new(
                    &mut *file,
                    &base64::engine::general_purpose::STANDARD,
                );
                encoder.write_all(&bin)?;
                encoder.finish()?;
            }
            file.write_all(tail.as_bytes())
        })
    }
}

/// Writes `path` through a temporary file in its directory, buffered, renamed into place
/// when `write` succeeds (removed when it fails).
fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), GltfError> {
    let write_error_io = |source| GltfError::Write {
        path: path.to_path_buf(),
        source,
    };
    crate::image::write_via_temp(
        path,
        |tmp| {
            let mut file = create_buffered(tmp).map_err(write_error_io)?;
            write(&mut file)
                .and_then(|()| file.flush())
                .map_err(write_error_io)
        },
        write_error_io,
    )
}

fn create_buffered(path: &Path) -> std::io::Result<std::io::BufWriter<std::fs::File>> {
    Ok(std::io::BufWriter::with_capacity(
        1 << 20,
        std::fs::File::create(path)?,
    ))
}

fn write_error(path: &Path, e: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> GltfError {
    GltfError::Write {
        path: path.to_path_buf(),
        source: std::io::Error::other(e),
    }
}

/// The binary buffer with its buffer views and accessors.
#[derive(Default)]
pub(super) struct BinWriter {
    pub(super) bin: Vec<u8>,
    pub(super) views: Vec<Value>,
    pub(super) accessors: Vec<Value>,
}

impl BinWriter {
    pub(super) fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        self.view_of(bytes.iter().copied(), target)
    }

    /// A buffer view of `bytes`, written straight into the buffer (no copy of them first).
    pub(super) fn view_of(
        &mut self,
        bytes: impl Iterator<Item = u8>,
        target: Option<u32>,
    ) -> usize {
        self.pad();
        let start = self.bin.len();
        self.bin.extend(bytes);
        let mut view = json!({
            "buffer": 0,
            "byteOffset": start,
            "byteLength": self.bin.len() - start,
        });
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.pad();
        self.views.push(view);
        self.views.len() - 1
    }

    pub(super) fn pad(&mut self) {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
    }

    pub(super) fn floats(
        &mut self,
        values: impl Iterator<Item = f32>,
        count: usize,
        ty: &str,
    ) -> Value {
        let view = self.view_of(values.flat_map(f32::to_le_bytes), Some(GL_ARRAY_BUFFER));
        json!({
            "bufferView": view,
            "componentType": GL_FLOAT,
            "count": count,
            "type": ty,
        })
    }

    pub(super) fn push(&mut self, accessor: Value) -> usize {
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    pub(super) fn vec3(&mut self, data: &[Vec3], bounds: bool) -> usize {
        let mut acc = self.floats(data.iter().flat_map(|v| v.to_array()), data.len(), "VEC3");
        if bounds {
            let min = data.iter().fold(Vec3::INFINITY, |a, &b| a.min(b));
            let max = data.iter().fold(Vec3::NEG_INFINITY, |a, &b| a.max(b));
            acc["min"] = json!(min.to_array());
            acc["max"] = json!(max.to_array());
        }
        self.push(acc)
    }

    pub(super) fn vec2(&mut self, data: &[Vec2]) -> usize {
        let acc = self.floats(data.iter().flat_map(|v| v.to_array()), data.len(), "VEC2");
        self.push(acc)
    }

    pub(super) fn indices(&mut self, data: &[u32]) -> usize {
        let view = self.view_of(
            data.iter().flat_map(|i| i.to_le_bytes()),
            Some(GL_ELEMENT_ARRAY_BUFFER),
        );
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
fn build_document(
    scene: &Scene,
    checked: &Scene,
    extra: &[VertexAttribute],
) -> Result<(Value, Vec<u8>), String> {
    let mut w = BinWriter::default();
    let mut extensions_used: BTreeSet<&str> = BTreeSet::new();

    // Textures referenced by materials, in index order, embedded as sRGB PNGs.
    let referenced: BTreeSet<u32> = scene
        .materials
        .iter()
        .flat_map(|m| {
            [
                m.albedo_texture,
                m.emission_texture.filter(|_| m.is_emissive()),
            ]
        })
        .flatten()
        .collect();
    let mut texture_map = BTreeMap::new();
    let mut images = Vec::new();
    let mut textures = Vec::new();
    let mut samplers = Vec::new();
    for &t in &referenced {
        let tex = &scene.textures[t as usize];
        let png = encode_png(tex).map_err(|e| format!("texture {t} '{}': {e}", tex.name))?;
        let view = w.view(&png, None);
        images.push(named(
            json!({ "bufferView": view, "mimeType": "image/png" }),
            &tex.name,
        ));
        texture_map.insert(t, textures.len());
        // One sampler per texture, in the same order.
        textures.push(named(
            json!({ "source": images.len() - 1, "sampler": textures.len() }),
            &tex.name,
        ));
        samplers.push(sampler_json(&tex.sampler));
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
            if let Some(c) = m.alpha_cutoff.filter(|&c| c > 0.0) {
                mat["alphaMode"] = json!("MASK");
                mat["alphaCutoff"] = json!(c);
            }
            if m.emission.max_element() > 1.0 {
                let (factor, strength) = split_scale(m.emission);
                mat["emissiveFactor"] = json!(factor);
                mat["extensions"] =
                    json!({ EXT_EMISSIVE_STRENGTH: { "emissiveStrength": strength } });
                extensions_used.insert(EXT_EMISSIVE_STRENGTH);
            } else if m.is_emissive() {
                mat["emissiveFactor"] = json!(m.emission.to_array());
            }
            if let Some(t) = m
                .emission_texture
                .filter(|_| m.is_emissive())
                .and_then(|t| texture_map.get(&t))
            {
                mat["emissiveTexture"] = json!({ "index": t });
            }
            mat
        })
        .collect();

    // The geometry's bytes, reserved at once (a vertex a run uses once per run, which
    // repeats only the vertices shared by two materials' runs): grown by doubling, the
    // buffer held its old and its new capacity while it was copied (the Breakfast Room's
    // relighting export has 85 MB of geometry; the job's peak RSS went 695 -> 663 MB).
    let geometry: usize = scene
        .meshes
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let per_vertex = 24
                + 8 * usize::from(m.uvs.is_some())
                + 12 * usize::from(m.colors.is_some())
                + 12 * extra.iter().filter(|a| a.mesh == i).count();
            m.positions.len() * per_vertex + m.indices.len() * 12
        })
        .sum();
    w.bin.reserve(geometry);
    let mut meshes = Vec::new();
    let mut nodes = Vec::new();
    for (mesh_index, (mesh, fixed)) in scene.meshes.iter().zip(&checked.meshes).enumerate() {
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
            if let Some(colors) = mesh
                .colors
                .as_ref()
                .filter(|c| c.len() == mesh.positions.len())
            {
                let c: Vec<Vec3> = used.iter().map(|&v| colors[v as usize]).collect();
                attributes["COLOR_0"] = json!(w.vec3(&c, false));
            }
            for a in extra.iter().filter(|a| a.mesh == mesh_index) {
                let values: Vec<Vec3> = used.iter().map(|&v| a.values[v as usize]).collect();
                attributes[a.name.as_str()] = json!(w.vec3(&values, false));
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
        let mut node = json!({
            "translation": l.position.to_array(),
            "extensions": { EXT_LIGHTS: { "light": lights.len() } },
        });
        if let Some(c) = &l.cone {
            // A spot points along its node's -Z.
            light["type"] = json!("spot");
            light["spot"] = json!({ "innerConeAngle": c.inner, "outerConeAngle": c.outer });
            let rotation = Quat::from_rotation_arc(Vec3::NEG_Z, c.axis()).normalize();
            node["rotation"] = json!(rotation.to_array());
        }
        lights.push(light);
        nodes.push(named(node, &l.name));
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
        let right = forward.cross(c.view_up()).normalize();
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
        root["samplers"] = json!(samplers);
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

/// Encodes linear texels as an 8-bit sRGB PNG, RGBA with linear alpha when the texture
/// has alpha.
fn encode_png(tex: &Texture) -> Result<Vec<u8>, String> {
    let srgb = |x: f32| (linear_to_srgb(x) * 255.0).round() as u8;
    let size_fault = || {
        format!(
            "{} texels for {}x{}",
            tex.texels.len(),
            tex.width,
            tex.height
        )
    };
    let mut out = std::io::Cursor::new(Vec::new());
    match &tex.alpha {
        Some(alpha) if alpha.len() == tex.texels.len() => {
            let bytes: Vec<u8> = tex
                .texels
                .iter()
                .zip(alpha)
                .flat_map(|(c, &a)| {
                    let [r, g, b] = c.to_array().map(srgb);
                    [r, g, b, (a.clamp(0.0, 1.0) * 255.0).round() as u8]
                })
                .collect();
            image::RgbaImage::from_raw(tex.width, tex.height, bytes)
                .ok_or_else(size_fault)?
                .write_to(&mut out, image::ImageFormat::Png)
        }
        _ => {
            let bytes: Vec<u8> = tex
                .texels
                .iter()
                .flat_map(|c| c.to_array().map(srgb))
                .collect();
            image::RgbImage::from_raw(tex.width, tex.height, bytes)
                .ok_or_else(size_fault)?
                .write_to(&mut out, image::ImageFormat::Png)
        }
    }
    .map_err(|e| e.to_string())?;
    Ok(out.into_inner())
}

/// A glTF sampler for `s`: its wrap per axis, and its filter for both magnification and
/// minification.
fn sampler_json(s: &crate::scene::Sampler) -> Value {
    use crate::scene::Wrap;
    let wrap = |w: Wrap| match w {
        Wrap::Repeat => GL_REPEAT,
        Wrap::ClampToEdge => GL_CLAMP_TO_EDGE,
        Wrap::MirroredRepeat => GL_MIRRORED_REPEAT,
    };
    let filter = if s.nearest { GL_NEAREST } else { GL_LINEAR };
    json!({
        "magFilter": filter,
        "minFilter": filter,
        "wrapS": wrap(s.wrap_u),
        "wrapT": wrap(s.wrap_v),
    })
}
