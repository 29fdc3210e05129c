//! Export of a scene and camera as a Mitsuba 3 scene, so the reference path tracer can be
//! timed and checked against an independent renderer on any scene the toolkit loads
//! (`cargo xtask reference --mitsuba DIR`; `xtask/scripts/mitsuba_render.py` renders it).
//!
//! What is written into the directory:
//! - `scene.xml`: every BSDF a `twosided` `diffuse` (the toolkit's surfaces reflect on both
//!   sides); Mitsuba's `path` integrator with the bounce limit mapped to `max_depth`
//!   (bounce limit `b` is `max_depth = b + 2`: one vertex for the camera ray's hit, one for
//!   its direct light; unlimited is `-1`), Russian roulette from the fourth vertex as ours, a
//!   perspective sensor with the camera's vertical field of view and a box filter, and one
//!   `ply` shape per (mesh, material) pair.
//! - `mesh_M_K.ply`: positions, normals and texture coordinates (binary little endian).
//! - `albedo_K.exr`, `emission_K.exr`, `opacity_K.exr`: a textured material's albedo texture
//!   with its factor multiplied in (Mitsuba has no product of a colour and a bitmap in its
//!   diffuse BSDF), the same for emission, and, for masked materials, the mask as 0/1
//!   (alpha against the cutoff) read with nearest filtering by a `mask` BSDF.
//! - `sky.exr`: the sky's equirectangular map (+Y up, row 0 the zenith, as Mitsuba's
//!   `envmap` reads it).
//!
//! Point lights become `point` emitters (spot cones become `spot` emitters with the outer
//! angle as cutoff and the inner as beam width: Mitsuba's falloff between them is its own, so
//! a scene with spots is only approximately the same scene), directional lights
//! `directional`. Vertex colours are not exported (Mitsuba's diffuse BSDF cannot multiply a
//! vertex attribute with a texture); the loader's own names are kept out of the files.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};
use scene_core::{Camera, Image, Scene, Texture, Wrap};

/// What went wrong writing a Mitsuba scene.
#[derive(Debug, thiserror::Error)]
pub enum MitsubaError {
    /// A file could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A texture could not be written as EXR.
    #[error("{path}: {message}")]
    Texture {
        /// The file.
        path: PathBuf,
        /// The cause.
        message: String,
    },
}

/// Writes `scene` seen from `camera` at `width` x `height`, `spp` samples per pixel and the
/// bounce limit `bounces` (`None`: unlimited) as a Mitsuba 3 scene in `dir` (created if
/// missing). Returns the path of `scene.xml`.
pub fn export(
    scene: &Scene,
    camera: &Camera,
    width: u32,
    height: u32,
    spp: u32,
    bounces: Option<u32>,
    dir: &Path,
) -> Result<PathBuf, MitsubaError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| MitsubaError::Io { path, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let max_depth = bounces.map_or(-1, |b| i64::from(b) + 2);
    let mut xml = String::from("<scene version=\"3.0.0\">\n");
    let _ = writeln!(
        xml,
        "  <integrator type=\"path\">\n    <integer name=\"max_depth\" value=\"{max_depth}\"/>\n    <integer name=\"rr_depth\" value=\"4\"/>\n  </integrator>"
    );
    let v = |p: Vec3| format!("{}, {}, {}", p.x, p.y, p.z);
    let _ = writeln!(
        xml,
        "  <sensor type=\"perspective\">\n    <string name=\"fov_axis\" value=\"y\"/>\n    <float name=\"fov\" value=\"{}\"/>\n    <float name=\"near_clip\" value=\"{}\"/>\n    <float name=\"far_clip\" value=\"{}\"/>\n    <transform name=\"to_world\">\n      <lookat origin=\"{}\" target=\"{}\" up=\"{}\"/>\n    </transform>\n    <sampler type=\"independent\">\n      <integer name=\"sample_count\" value=\"{spp}\"/>\n    </sampler>\n    <film type=\"hdrfilm\">\n      <integer name=\"width\" value=\"{width}\"/>\n      <integer name=\"height\" value=\"{height}\"/>\n      <string name=\"pixel_format\" value=\"rgb\"/>\n      <rfilter type=\"box\"/>\n    </film>\n  </sensor>",
        camera.fov_y.to_degrees(),
        camera.near,
        camera.far,
        v(camera.position),
        v(camera.target),
        v(camera.up),
    );

    // Materials: one BSDF each (textures baked with their factor).
    for (k, m) in scene.materials.iter().enumerate() {
        let albedo = match m
            .albedo_texture
            .and_then(|t| scene.textures.get(t as usize))
        {
            Some(t) => {
                let name = format!("albedo_{k}.exr");
                write_texture(t, m.albedo, &dir.join(&name))?;
                bitmap("reflectance", &name, t, false)
            }
            None => format!("<rgb name=\"reflectance\" value=\"{}\"/>", v(m.albedo)),
        };
        // Two-sided, as the toolkit's surfaces reflect (Mitsuba's diffuse BSDF alone is
        // black from behind).
        let diffuse = |id: &str| {
            format!(
                "<bsdf type=\"twosided\"{id}>\n      <bsdf type=\"diffuse\">\n        {albedo}\n      </bsdf>\n    </bsdf>"
            )
        };
        let masked = m
            .alpha_cutoff
            .filter(|c| *c > 0.0)
            .and_then(|c| Some((c, scene.textures.get(m.albedo_texture? as usize)?)));
        let bsdf = match masked {
            Some((cutoff, t)) => {
                let name = format!("opacity_{k}.exr");
                let mask: Vec<Vec3> = (0..t.texels.len())
                    .map(|i| {
                        let a = t.alpha.as_ref().map_or(1.0, |a| a[i]);
                        Vec3::splat(if a >= cutoff { 1.0 } else { 0.0 })
                    })
                    .collect();
                write_exr(t.width, t.height, mask, &dir.join(&name))?;
                format!(
                    "<bsdf type=\"mask\" id=\"m{k}\">\n    {}\n    {}\n  </bsdf>",
                    bitmap("opacity", &name, t, true),
                    diffuse("")
                )
            }
            None => diffuse(&format!(" id=\"m{k}\"")),
        };
        let _ = writeln!(xml, "  {bsdf}");
    }

    // Shapes: one PLY per mesh and material.
    for (mi, mesh) in scene.meshes.iter().enumerate() {
        let mut by_material: std::collections::BTreeMap<u32, Vec<usize>> = Default::default();
        for (t, &m) in mesh.material_ids.iter().enumerate() {
            by_material.entry(m).or_default().push(t);
        }
        for (m, tris) in by_material {
            let name = format!("mesh_{mi}_{m}.ply");
            let path = dir.join(&name);
            write_ply(mesh, &tris, &path).map_err(io(&path))?;
            let mat = &scene.materials[m as usize];
            let emitter = if mat.is_emissive() {
                let radiance = match mat
                    .emission_texture
                    .and_then(|t| scene.textures.get(t as usize))
                {
                    Some(t) => {
                        let tex = format!("emission_{m}.exr");
                        if !dir.join(&tex).exists() {
                            write_texture(t, mat.emission, &dir.join(&tex))?;
                        }
                        bitmap("radiance", &tex, t, false)
                    }
                    None => format!("<rgb name=\"radiance\" value=\"{}\"/>", v(mat.emission)),
                };
                format!("\n    <emitter type=\"area\">\n      {radiance}\n    </emitter>")
            } else {
                String::new()
            };
            let _ = writeln!(
                xml,
                "  <shape type=\"ply\">\n    <string name=\"filename\" value=\"{name}\"/>\n    <ref id=\"m{m}\"/>{emitter}\n  </shape>"
            );
        }
    }

    for l in &scene.point_lights {
        match &l.cone {
            None => {
                let _ = writeln!(
                    xml,
                    "  <emitter type=\"point\">\n    <point name=\"position\" value=\"{}\"/>\n    <rgb name=\"intensity\" value=\"{}\"/>\n  </emitter>",
                    v(l.position),
                    v(l.intensity)
                );
            }
            Some(c) => {
                let _ = writeln!(
                    xml,
                    "  <emitter type=\"spot\">\n    <transform name=\"to_world\">\n      <lookat origin=\"{}\" target=\"{}\"/>\n    </transform>\n    <rgb name=\"intensity\" value=\"{}\"/>\n    <float name=\"cutoff_angle\" value=\"{}\"/>\n    <float name=\"beam_width\" value=\"{}\"/>\n  </emitter>",
                    v(l.position),
                    v(l.position + c.direction.normalize_or_zero()),
                    v(l.intensity),
                    c.outer.to_degrees(),
                    c.inner.to_degrees()
                );
            }
        }
    }
    for l in &scene.directional_lights {
        let _ = writeln!(
            xml,
            "  <emitter type=\"directional\">\n    <vector name=\"direction\" value=\"{}\"/>\n    <rgb name=\"irradiance\" value=\"{}\"/>\n  </emitter>",
            v(l.direction),
            v(l.irradiance)
        );
    }
    if let Some(sky) = scene.sky.as_ref().filter(|s| !s.is_black()) {
        let (w, h) = sky.size();
        write_exr(w, h, sky.map().to_vec(), &dir.join("sky.exr"))?;
        let _ = writeln!(
            xml,
            "  <emitter type=\"envmap\">\n    <string name=\"filename\" value=\"sky.exr\"/>\n  </emitter>"
        );
    }
    xml.push_str("</scene>\n");
    let path = dir.join("scene.xml");
    std::fs::write(&path, xml).map_err(io(&path))?;
    Ok(path)
}

/// A `bitmap` texture element named `name` reading `file` with `t`'s sampler (Mitsuba
/// wraps both axes alike: u's mode is used). `raw`: no colour conversion (all exported
/// textures are linear).
fn bitmap(name: &str, file: &str, t: &Texture, nearest: bool) -> String {
    let wrap = match t.sampler.wrap_u {
        Wrap::Repeat => "repeat",
        Wrap::ClampToEdge => "clamp",
        Wrap::MirroredRepeat => "mirror",
    };
    let filter = if nearest || t.sampler.nearest {
        "nearest"
    } else {
        "bilinear"
    };
    format!(
        "<texture type=\"bitmap\" name=\"{name}\">\n        <string name=\"filename\" value=\"{file}\"/>\n        <string name=\"filter_type\" value=\"{filter}\"/>\n        <string name=\"wrap_mode\" value=\"{wrap}\"/>\n        <boolean name=\"raw\" value=\"true\"/>\n      </texture>"
    )
}

fn write_texture(t: &Texture, factor: Vec3, path: &Path) -> Result<(), MitsubaError> {
    let texels = t.texels.iter().map(|&c| c * factor).collect();
    write_exr(t.width, t.height, texels, path)
}

fn write_exr(w: u32, h: u32, pixels: Vec<Vec3>, path: &Path) -> Result<(), MitsubaError> {
    let fail = |message: String| MitsubaError::Texture {
        path: path.to_path_buf(),
        message,
    };
    Image::from_pixels(w, h, pixels)
        .map_err(|e| fail(e.to_string()))?
        .write_exr(path)
        .map_err(|e| fail(e.to_string()))
}

/// The triangles `tris` of `mesh` as a binary PLY with their own vertices.
fn write_ply(mesh: &scene_core::Mesh, tris: &[usize], path: &Path) -> std::io::Result<()> {
    let mut remap = std::collections::HashMap::new();
    let mut verts: Vec<u32> = Vec::new();
    let mut faces: Vec<[u32; 3]> = Vec::with_capacity(tris.len());
    for &t in tris {
        let tri = mesh.indices[t];
        faces.push(tri.map(|i| {
            *remap.entry(i).or_insert_with(|| {
                verts.push(i);
                verts.len() as u32 - 1
            })
        }));
    }
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        verts.len(),
        faces.len()
    )?;
    for &i in &verts {
        let p = mesh.positions[i as usize];
        let n = mesh.normals[i as usize];
        let uv = mesh.uvs.as_ref().map_or(Vec2::ZERO, |u| u[i as usize]);
        for f in [p.x, p.y, p.z, n.x, n.y, n.z, uv.x, uv.y] {
            out.write_all(&f.to_le_bytes())?;
        }
    }
    for f in faces {
        out.write_all(&[3u8])?;
        for i in f {
            out.write_all(&(i as i32).to_le_bytes())?;
        }
    }
    out.flush()
}
