//! Fuzz targets: what `cargo xtask fuzz` feeds mutated files to, with the seed files the
//! project writes itself, and the replay of every input that ever failed
//! (`tests/fuzz-regressions/<target>/`, replayed by `tests/tests/fuzz_regressions.rs`).
//!
//! A target takes bytes and returns `Ok` or a typed error turned into text; both are fine.
//! A panic, an abort, an allocation past the memory cap or an input that runs past the time
//! limit is a finding.

use std::path::{Path, PathBuf};

use scene_core::budget::Budget;
use scene_core::gltf_io::{self, ImportOptions};
use scene_core::{Image, Scene, builtin};

use crate::hostile;

/// Everything a target needs besides the input.
pub struct Context {
    /// The budget every loader runs under.
    pub budget: Budget,
    /// A directory the gltf target writes its input into (as `scene/fuzz.gltf`, beside
    /// `scene/buf.bin`; `outside.bin` lies one level up, outside the scene's folder).
    pub scratch: PathBuf,
    /// The scene camera lists are parsed for.
    pub cornell: Scene,
}

impl Context {
    /// A context whose scratch directory is `scratch` (created and filled here).
    pub fn new(budget: Budget, scratch: &Path) -> Self {
        let scene_dir = scratch.join("scene");
        std::fs::create_dir_all(&scene_dir).expect("fuzz scratch directory");
        std::fs::write(scene_dir.join("buf.bin"), hostile::triangle_buffer()).expect("buf.bin");
        std::fs::write(scratch.join("outside.bin"), hostile::triangle_buffer())
            .expect("outside.bin");
        Self {
            budget,
            scratch: scratch.to_path_buf(),
            cornell: builtin::scene("cornell").expect("cornell"),
        }
    }
}

/// The budget of fuzzing runs and of the regression replay: small enough that a worker
/// under a 3 GiB address space can honour it with room to spare, large enough for every
/// seed.
pub fn fuzz_budget() -> Budget {
    Budget {
        file_bytes: 64 << 20,
        image_bytes: 256 << 20,
        vertices: 1 << 22,
        indices: 3 << 22,
        scene_bytes: 512 << 20,
    }
}

/// One thing to fuzz.
pub struct Target {
    /// Its name (`cargo xtask fuzz --target NAME`, and the regression folder).
    pub name: &'static str,
    /// File extension of its inputs.
    pub ext: &'static str,
    /// Whether inputs are JSON text (the fuzzer then also mutates parsed values).
    pub json: bool,
    /// The seed files.
    pub seeds: fn() -> Vec<Vec<u8>>,
    /// Runs one input.
    pub run: fn(&[u8], &Context) -> Result<(), String>,
}

/// Every target.
pub fn targets() -> Vec<Target> {
    vec![
        Target {
            name: "gltf",
            ext: "gltf",
            json: true,
            seeds: gltf_seeds,
            run: run_gltf,
        },
        Target {
            name: "glb",
            ext: "glb",
            json: false,
            seeds: || {
                let mut s: Vec<Vec<u8>> = scenes().map(|n| hostile::exported(n, "glb")).collect();
                s.push(hostile::exported_scene(
                    &hostile::material_features(),
                    "glb",
                ));
                s
            },
            run: |bytes, ctx| {
                let options = ImportOptions {
                    budget: ctx.budget,
                    ..Default::default()
                };
                refused(gltf_io::import_slice_with(
                    bytes,
                    Path::new("fuzz.glb"),
                    &options,
                ))
            },
        },
        Target {
            name: "exr",
            ext: "exr",
            json: false,
            seeds: || {
                let mut s = vec![hostile::small_exr(7, 5), hostile::exr_b44_overflow()];
                s.extend(hostile::exr_variants());
                s
            },
            run: |bytes, ctx| refused(Image::decode_exr(bytes, Path::new("fuzz.exr"), &ctx.budget)),
        },
        Target {
            name: "png",
            ext: "png",
            json: false,
            seeds: png_seeds,
            run: |bytes, ctx| refused(Image::decode_png(bytes, Path::new("fuzz.png"), &ctx.budget)),
        },
        Target {
            name: "cameras",
            ext: "json",
            json: true,
            seeds: || {
                let mut s: Vec<Vec<u8>> = hostile::bad_camera_lists()
                    .into_iter()
                    .map(|(_, t)| t.into_bytes())
                    .collect();
                s.push(
                    br#"{"cameras": [{"name": "a", "position": [0.278, 0.273, -0.8], "target": [0.278, 0.273, 0], "up": [0, 1, 0], "fov": 40, "near": 0.01, "far": 5}]}"#
                        .to_vec(),
                );
                s
            },
            run: |bytes, ctx| {
                let text = std::str::from_utf8(bytes).map_err(|e| e.to_string())?;
                let cams = bench_harness::parse_camera_list(text, &ctx.cornell, "fuzz.json")
                    .map_err(|e| e.to_string())?;
                // What the list admits must be a camera a scene admits.
                for (i, c) in cams.iter().enumerate() {
                    if let Err(e) = c.check(i) {
                        panic!("camera list admitted a camera Scene::validate refuses: {e}");
                    }
                }
                Ok(())
            },
        },
        Target {
            name: "scenes",
            ext: "json",
            json: true,
            seeds: scene_spec_seeds,
            run: run_scene_spec,
        },
    ]
}

/// The scene fuzz target's seeds: specs of random small scenes ([`crate::scenes::random_scene`])
/// and of the hard cases the scene contract names (spots among them), as JSON (so the fuzzer also sets their
/// numbers to 0, -1, 1e39, 1e-45 ...).
fn scene_spec_seeds() -> Vec<Vec<u8>> {
    let mut s: Vec<String> = (0..8).map(|i| format!("{{\"seed\": {i}}}")).collect();
    s.extend(
        [
            r#"{"seed": 1, "intensity": 1e38}"#,
            r#"{"seed": 2, "albedo": [0.999, 0.999, 0.999], "emission": 5}"#,
            r#"{"seed": 3, "offset": [1e7, 0, 0]}"#,
            r#"{"seed": 4, "offset": [60, -35, 70], "scale": 1e3}"#,
            r#"{"seed": 5, "camera": {"target": [0.5, -1, 0.5], "up": [0, 1, 0]}}"#,
            r#"{"seed": 6, "camera": {"fov": 179.9, "near": 1e-30, "far": 1e30}}"#,
            r#"{"seed": 7, "lights": false, "emission": 0}"#,
            r#"{"seed": 8, "triangles": false}"#,
            r#"{"seed": 1, "spot": [0.3, 0.6]}"#,
            r#"{"seed": 3, "spot": [0, 1.5707964], "offset": [1e3, 0, 0]}"#,
            r#"{"seed": 4, "mask": 0.5, "tint": [0.9, 0.5, 0.2]}"#,
            r#"{"seed": 5, "mask": 1.5, "lights": false}"#,
            r#"{"seed": 6, "sky": [0.5, 0.6, 0.8], "lights": false}"#,
            r#"{"seed": 2, "sky": [1, 1, 1], "sky_directions": 3, "offset": [1e3, 0, 0]}"#,
            r#"{"seed": 1, "sky_map": [1, 1], "lights": false}"#,
            r#"{"seed": 2, "sky_map": [4096, 1], "sky_directions": 16}"#,
            r#"{"seed": 3, "sky_map": [1, 7], "lights": false}"#,
            r#"{"seed": 4, "sky_map": [3, 5], "sky_directions": 1}"#,
            r#"{"seed": 5, "far_point": [1e38, 1e38, 1e38]}"#,
            r#"{"seed": 6, "far_point": [-3e38, 0, 1e-30], "lights": false}"#,
            r#"{"seed": 7, "emitter_mask": 0.5, "emission": 5}"#,
            r#"{"seed": 1, "emitter_mask": 1.5, "lights": false, "emission": 5}"#,
        ]
        .map(String::from),
    );
    s.into_iter().map(String::into_bytes).collect()
}

/// Runs one scene spec through the scene contract: the scene is built (a random small scene
/// from `seed`, then the spec's overrides), validated as a loader would, and every method
/// renders its first camera at 8x6 on the CPU. A refusal (validation, the contract, a
/// method's typed error) is an outcome; an image with a non-finite or negative pixel, or a
/// panic, is a finding.
pub fn run_scene_spec(bytes: &[u8], _ctx: &Context) -> Result<(), String> {
    use scene_core::glam::Vec3;
    let v: serde_json::Value = serde_json::from_slice(bytes).map_err(|e| e.to_string())?;
    let num = |k: &str| v.get(k).and_then(|x| x.as_f64()).map(|x| x as f32);
    let vec3 = |x: Option<&serde_json::Value>| -> Option<Vec3> {
        let a = x?.as_array()?;
        (a.len() == 3).then(|| {
            Vec3::new(
                a[0].as_f64().unwrap_or(0.0) as f32,
                a[1].as_f64().unwrap_or(0.0) as f32,
                a[2].as_f64().unwrap_or(0.0) as f32,
            )
        })
    };
    let seed = v.get("seed").and_then(|x| x.as_u64()).unwrap_or(0);
    let mut s = crate::scenes::random_scene(seed);
    if let Some(i) = num("intensity") {
        s.point_lights
            .iter_mut()
            .for_each(|l| l.intensity = Vec3::splat(i));
    }
    // A spot: the point lights (one is added if there is none) get a cone of [inner,
    // outer] radians pointing down.
    if let Some(a) = v.get("spot").and_then(|x| x.as_array())
        && a.len() == 2
    {
        let angle = |i: usize| a[i].as_f64().unwrap_or(0.0) as f32;
        if s.point_lights.is_empty() {
            // Inside the smallest room random_scene makes.
            s.point_lights.push(scene_core::PointLight::new(
                "spot",
                Vec3::new(0.5, 0.45, 0.5),
                Vec3::ONE,
            ));
        }
        for l in &mut s.point_lights {
            l.cone = Some(scene_core::lights::SpotCone {
                direction: Vec3::new(0.1, -1.0, 0.05),
                inner: angle(0),
                outer: angle(1),
            });
        }
    }
    if let Some(a) = vec3(v.get("albedo")) {
        s.materials[0].albedo = a;
    }
    // An alpha mask on material 0 (`mask`) or on the emissive material 2 (`emitter_mask`):
    // a 4 x 4 checkerboard of alpha 0 and 1 (nearest) over texture coordinates from x and
    // z, cut at the value given.
    for (key, material) in [("mask", 0usize), ("emitter_mask", 2)] {
        let Some(c) = num(key) else {
            continue;
        };
        s.textures.push(scene_core::Texture {
            name: "fuzz mask".into(),
            width: 4,
            height: 4,
            texels: vec![Vec3::ONE; 16],
            alpha: Some((0..16).map(|i| ((i + i / 4) % 2) as f32).collect()),
            sampler: scene_core::Sampler {
                nearest: true,
                ..Default::default()
            },
        });
        s.materials[material].albedo_texture = Some(s.textures.len() as u32 - 1);
        s.materials[material].alpha_cutoff = Some(c);
        for m in &mut s.meshes {
            let uvs = m
                .positions
                .iter()
                .map(|p| scene_core::glam::Vec2::new(p.x, p.z) * 2.0);
            m.uvs = Some(uvs.collect());
        }
    }
    // Vertex colours on every mesh.
    if let Some(t) = vec3(v.get("tint")) {
        for m in &mut s.meshes {
            m.colors = Some(vec![t; m.positions.len()]);
        }
    }
    if let Some(e) = num("emission") {
        s.materials[2].emission = Vec3::splat(e);
    }
    if v.get("lights").and_then(|x| x.as_bool()) == Some(false) {
        s.point_lights.clear();
        s.directional_lights.clear();
    }
    // A point light of intensity 1 at `far_point` (near f32's limits: rays from it).
    if let Some(p) = vec3(v.get("far_point")) {
        s.point_lights
            .push(scene_core::PointLight::new("far", p, Vec3::ONE));
    }
    // A uniform sky of radiance `sky`, as `sky_directions` directional lights for the
    // methods that do not integrate it; a sky the model refuses is a typed outcome.
    let directions = num("sky_directions").map_or(scene_core::sky::DEFAULT_DIRECTIONS, |n| {
        n.clamp(0.0, u32::MAX as f32) as u32
    });
    if let Some(l) = vec3(v.get("sky")) {
        match scene_core::sky::Sky::uniform(l).and_then(|sky| sky.with_directions(directions)) {
            Ok(sky) => s.sky = Some(sky),
            Err(_) => return Ok(()),
        }
    }
    // A `[w, h]` sky map (at most 2^16 pixels; a larger ask is a typed outcome) whose
    // radiance varies over it: 1x1, one row, one column, odd heights.
    if let Some(a) = v.get("sky_map").and_then(|x| x.as_array())
        && a.len() == 2
    {
        let side = |i: usize| a[i].as_u64().unwrap_or(0).min(1 << 16) as u32;
        let (w, h) = (side(0), side(1));
        if u64::from(w) * u64::from(h) > 1 << 16 {
            return Ok(());
        }
        let map = (0..w * h)
            .map(|i| Vec3::new(0.2 + (i % 7) as f32 * 0.1, 0.5, 0.9 - (i % 5) as f32 * 0.1))
            .collect();
        match scene_core::sky::Sky::from_map("fuzz map", w, h, map, directions) {
            Ok(sky) => s.sky = Some(sky),
            Err(_) => return Ok(()),
        }
    }
    if v.get("triangles").and_then(|x| x.as_bool()) == Some(false) {
        s.meshes.iter_mut().for_each(|m| {
            m.indices.clear();
            m.material_ids.clear();
        });
    }
    if let Some(c) = v.get("camera") {
        let cam = &mut s.cameras[0];
        if let Some(f) = c.get("fov").and_then(|x| x.as_f64()) {
            cam.fov_y = (f as f32).to_radians();
        }
        if let Some(n) = c.get("near").and_then(|x| x.as_f64()) {
            cam.near = n as f32;
        }
        if let Some(f) = c.get("far").and_then(|x| x.as_f64()) {
            cam.far = f as f32;
        }
        if let Some(t) = vec3(c.get("target")) {
            cam.target = t;
        }
        if let Some(u) = vec3(c.get("up")) {
            cam.up = u;
        }
    }
    if let Some(k) = num("scale") {
        s = s.scaled(k);
    }
    if let Some(t) = vec3(v.get("offset")) {
        s = s.translated(t);
    }
    s.validate().map_err(|e| e.to_string())?;
    let scene = std::sync::Arc::new(s);
    let (w, h) = (8, 6);
    let mut refusals = Vec::new();
    for (name, mut technique) in crate::scenes::techniques(None) {
        let outcome = crate::scenes::run(technique.as_mut(), &scene, w, h);
        if let Err(e) = crate::scenes::keeps_contract(&outcome, w, h) {
            panic!("{name} broke the scene contract on {}: {e}", scene.name);
        }
        if let crate::scenes::Outcome::Refused(e) = outcome {
            refusals.push(format!("{name}: {e}"));
        }
    }
    if refusals.is_empty() {
        Ok(())
    } else {
        Err(refusals.join("; "))
    }
}

/// A loader's result as a target's: loaded, or refused with the error's text.
fn refused<T, E: std::fmt::Display>(r: Result<T, E>) -> Result<(), String> {
    r.map(|_| ()).map_err(|e| e.to_string())
}

fn scenes() -> impl Iterator<Item = &'static str> {
    ["cornell", "cornell-point", "primitives", "corridor"].into_iter()
}

fn gltf_seeds() -> Vec<Vec<u8>> {
    let mut s: Vec<Vec<u8>> = scenes().map(|n| hostile::exported(n, "gltf")).collect();
    s.push(hostile::to_bytes(&hostile::triangle_json()));
    s.push(hostile::triangle_with_buffer_uri("buf.bin"));
    s.push(hostile::triangle_with_texture(&png_seeds()[0]));
    s.push(hostile::exported_scene(
        &hostile::material_features(),
        "gltf",
    ));
    s.push(hostile::sparse_instanced(4, 3));
    s.push(hostile::camera_type_mismatch());
    s
}

fn run_gltf(bytes: &[u8], ctx: &Context) -> Result<(), String> {
    let path = ctx.scratch.join("scene").join("fuzz.gltf");
    std::fs::write(&path, bytes).map_err(|e| format!("fuzz harness: {e}"))?;
    let options = ImportOptions {
        budget: ctx.budget,
        ..Default::default()
    };
    refused(gltf_io::import_with(&path, &options))
}

fn png_seeds() -> Vec<Vec<u8>> {
    let dir = hostile::scratch_dir("png-seeds");
    let mut img = Image::new(5, 3);
    for (i, p) in img.pixels.iter_mut().enumerate() {
        *p = scene_core::glam::Vec3::new(i as f32 / 15.0, 0.5, 1.0 - i as f32 / 15.0);
    }
    let path = dir.join("seed.png");
    img.write_png(&path, 0.0).expect("seed PNG");
    let mut seeds = vec![std::fs::read(&path).expect("seed PNG bytes")];
    let _ = std::fs::remove_dir_all(&dir);
    seeds.push(hostile::png_bomb(16));
    // 16-bit RGBA and 8-bit grey-alpha, written with the png crate.
    for (color, depth, channels, bytes_per) in [
        (png::ColorType::Rgba, png::BitDepth::Sixteen, 4, 2),
        (png::ColorType::GrayscaleAlpha, png::BitDepth::Eight, 2, 1),
        (png::ColorType::Rgb, png::BitDepth::Eight, 3, 1),
    ] {
        let (w, h) = (6u32, 4u32);
        let data: Vec<u8> = (0..w * h * channels * bytes_per)
            .map(|i| (i * 37 % 251) as u8)
            .collect();
        let mut out = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut out, w, h);
            enc.set_color(color);
            enc.set_depth(depth);
            let mut writer = enc.write_header().expect("PNG header");
            writer.write_image_data(&data).expect("PNG data");
        }
        seeds.push(out);
    }
    seeds
}

/// How one input ended.
#[derive(Debug, PartialEq)]
pub enum Outcome {
    /// Loaded.
    Ok,
    /// Refused with an error (the message).
    Refused(String),
    /// Panicked (the panic message): a finding.
    Panicked(String),
}

/// Runs `target` on `bytes`, catching a panic.
pub fn run(target: &Target, bytes: &[u8], ctx: &Context) -> Outcome {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| (target.run)(bytes, ctx))) {
        Ok(Ok(())) => Outcome::Ok,
        Ok(Err(e)) => Outcome::Refused(e),
        Err(payload) => Outcome::Panicked(scene_core::image::panic_message(payload.as_ref())),
    }
}

/// `tests/fuzz-regressions`: one folder per target holding every input that ever failed.
pub fn regressions_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz-regressions")
}

/// The saved failing inputs of `target`, sorted by name.
pub fn regressions(target: &Target) -> Vec<PathBuf> {
    let dir = regressions_root().join(target.name);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file())
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files
}

/// FNV-1a of the bytes, as 16 hex digits: the file name a finding is saved under.
pub fn content_name(bytes: &[u8]) -> String {
    format!(
        "{:016x}",
        scene_core::hash::Fnv::default().bytes(bytes).finish()
    )
}
