//! Hostile files, written by code: each is a few hundred bytes to a few hundred kilobytes
//! and asks a loader for something it must refuse (gigabytes of memory, a file outside the
//! scene's folder, a projection that is not there). The tests in `tests/tests/hostile_files.rs`
//! and `xtask/tests/hostile_cli.rs` and the fuzzer's seeds use them.

use std::io::Cursor;
use std::path::Path;

use base64::Engine as _;
use scene_core::{Image, builtin, glam::Vec3, gltf_io};
use serde_json::{Value, json};

/// A built-in scene exported as `.gltf` (`ext` "gltf") or `.glb` bytes.
pub fn exported(name: &str, ext: &str) -> Vec<u8> {
    exported_scene(&builtin::scene(name).expect("built-in scene"), ext)
}

/// `scene` exported as `.gltf` or `.glb` bytes.
pub fn exported_scene(scene: &scene_core::Scene, ext: &str) -> Vec<u8> {
    let name = scene
        .name
        .replace(|c: char| !c.is_ascii_alphanumeric(), "-");
    let dir = scratch_dir("export");
    let path = dir.join(format!("{name}.{ext}"));
    gltf_io::export(scene, &path).expect("export a scene");
    let bytes = std::fs::read(&path).expect("read the export back");
    let _ = std::fs::remove_dir_all(&dir);
    bytes
}

/// A fresh, empty directory under the system temp dir, unique to this process and `tag`.
pub fn scratch_dir(tag: &str) -> std::path::PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static N: AtomicU64 = AtomicU64::new(0);
    let dir = std::env::temp_dir().join(format!(
        "dgi-{tag}-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create a scratch directory");
    dir
}

/// The JSON of the exported Cornell box (with its buffer as a data URI), for editing.
pub fn cornell_json() -> Value {
    serde_json::from_slice(&exported("cornell", "gltf")).expect("exported JSON parses")
}

/// JSON text of `v`.
pub fn to_bytes(v: &Value) -> Vec<u8> {
    serde_json::to_vec(v).expect("JSON serialises")
}

/// The Cornell box whose camera says `"type": "orthographic"` but carries only a
/// `perspective` object (the `gltf` crate validates it, then unwraps the missing object).
pub fn camera_type_mismatch() -> Vec<u8> {
    let mut v = cornell_json();
    v["cameras"][0]["type"] = json!("orthographic");
    to_bytes(&v)
}

/// One triangle whose single buffer is the external `uri`.
pub fn triangle_with_buffer_uri(uri: &str) -> Vec<u8> {
    let mut v = triangle_json();
    v["buffers"][0]["uri"] = json!(uri);
    to_bytes(&v)
}

/// The bytes of [`triangle_with_buffer_uri`]'s buffer: three positions.
pub fn triangle_buffer() -> Vec<u8> {
    [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect()
}

fn data_uri(bytes: &[u8], mime: &str) -> String {
    format!(
        "data:{mime};base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// A one-triangle glTF (positions only) with its buffer as a data URI.
pub fn triangle_json() -> Value {
    let buffer = triangle_buffer();
    json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "bufferViews": [{"buffer": 0, "byteLength": buffer.len()}],
        "buffers": [{"byteLength": buffer.len(), "uri": data_uri(&buffer, "application/octet-stream")}]
    })
}

/// The one-triangle glTF with its node moved by `offset` along x: at 1e7 its f32 positions
/// are placed a metre apart for a triangle a metre wide (the scene contract's
/// `PrecisionLost`).
pub fn triangle_far_away(offset: f64) -> Vec<u8> {
    let mut v = triangle_json();
    v["nodes"][0]["translation"] = json!([offset, 0.0, 0.0]);
    to_bytes(&v)
}

/// A glTF with a camera and no mesh: nothing to render (the scene contract's `NoGeometry`).
pub fn camera_only() -> Vec<u8> {
    to_bytes(&json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"camera": 0, "translation": [0, 0, 2]}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01, "zfar": 10}}]
    }))
}

/// A glTF whose one mesh has a sparse-only `POSITION` accessor of `count` vertices (no
/// buffer view: every vertex is zero but one), drawn without indices, instanced by
/// `instances` nodes: a few hundred bytes that ask for `count x instances` vertices.
pub fn sparse_instanced(count: u64, instances: usize) -> Vec<u8> {
    // One sparse index (u32 0) and one value (three f32).
    let mut buffer: Vec<u8> = 0u32.to_le_bytes().to_vec();
    for f in [1.0f32, 2.0, 3.0] {
        buffer.extend(f.to_le_bytes());
    }
    let nodes: Vec<Value> = (0..instances).map(|_| json!({"mesh": 0})).collect();
    let v = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": (0..instances).collect::<Vec<_>>()}],
        "nodes": nodes,
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"componentType": 5126, "count": count, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 2, 3],
                       "sparse": {"count": 1,
                                  "indices": {"bufferView": 0, "componentType": 5125},
                                  "values": {"bufferView": 1}}}],
        "bufferViews": [{"buffer": 0, "byteLength": 4}, {"buffer": 0, "byteOffset": 4, "byteLength": 12}],
        "buffers": [{"byteLength": buffer.len(), "uri": data_uri(&buffer, "application/octet-stream")}]
    });
    to_bytes(&v)
}

/// A one-bit grey PNG of `side x side` pixels, all black: 66 KB at 16384, which decodes to
/// 256 M pixels (3 GiB as linear f32 RGB).
pub fn png_bomb(side: u32) -> Vec<u8> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, side, side);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::One);
        enc.set_compression(png::Compression::Balanced);
        let mut writer = enc.write_header().expect("PNG header");
        let row = vec![0u8; side.div_ceil(8) as usize];
        let mut stream = writer.stream_writer().expect("PNG stream");
        for _ in 0..side {
            std::io::Write::write_all(&mut stream, &row).expect("PNG row");
        }
        stream.finish().expect("PNG end");
    }
    out
}

/// A PNG of only a signature, an IHDR declaring `w x h` 8-bit grey pixels, an empty IDAT
/// and an IEND:
/// a few dozen bytes whose header alone asks for `w h` bytes (the `png` crate admits any
/// size whose byte count fits an `isize`).
pub fn png_header_only(w: u32, h: u32) -> Vec<u8> {
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = |kind: &[u8; 4], data: &[u8]| {
        out.extend((data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        out.extend_from_slice(&body);
        out.extend(crc32(&body).to_be_bytes());
    };
    let mut ihdr = Vec::new();
    ihdr.extend(w.to_be_bytes());
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([8, 0, 0, 0, 0]); // depth 8, grey, deflate, adaptive filter, no interlace
    chunk(b"IHDR", &ihdr);
    chunk(b"IDAT", &[]);
    chunk(b"IEND", &[]);
    out
}

/// CRC-32 (ISO 3309, as PNG chunks use).
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xffff_ffffu32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xedb8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// [`sparse_instanced`]`(3, 1)` with a second sparse-only accessor of `normals` elements
/// used as `NORMAL`: the `gltf` reader sizes its output from that count.
pub fn sparse_normals(normals: u64) -> Vec<u8> {
    let mut v: Value = serde_json::from_slice(&sparse_instanced(3, 1)).expect("JSON");
    let mut acc = v["accessors"][0].clone();
    acc["count"] = json!(normals);
    v["accessors"].as_array_mut().expect("accessors").push(acc);
    v["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(1);
    to_bytes(&v)
}

/// The one-triangle glTF with a material whose base colour texture is the embedded `png`.
pub fn triangle_with_texture(png: &[u8]) -> Vec<u8> {
    let mut v = triangle_json();
    v["meshes"][0]["primitives"][0]["material"] = json!(0);
    v["materials"] = json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
    v["textures"] = json!([{"source": 0}]);
    v["images"] = json!([{"uri": data_uri(png, "image/png")}]);
    to_bytes(&v)
}

/// A small valid RGB EXR (`w x h`, a gradient), as the toolkit writes them.
pub fn small_exr(w: u32, h: u32) -> Vec<u8> {
    let mut img = Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            img.set(
                x,
                y,
                Vec3::new(x as f32 / w as f32, y as f32 / h as f32, 0.25),
            );
        }
    }
    let dir = scratch_dir("exr");
    let path = dir.join("small.exr");
    img.write_exr(&path).expect("write a small EXR");
    let bytes = std::fs::read(&path).expect("read it back");
    let _ = std::fs::remove_dir_all(&dir);
    bytes
}

/// A valid EXR whose header's data window is rewritten to `w x h`: about 700 bytes that
/// ask a naive reader for `12 w h` bytes of pixels before any pixel is read.
pub fn exr_bomb(w: i32, h: i32) -> Vec<u8> {
    let mut bytes = small_exr(4, 4);
    let key = b"dataWindow\0box2i\0";
    let at = bytes
        .windows(key.len())
        .position(|win| win == key)
        .expect("the EXR header has a data window")
        + key.len()
        + 4; // the attribute's size field
    let window = [0i32, 0, w - 1, h - 1];
    for (i, v) in window.iter().enumerate() {
        bytes[at + 4 * i..at + 4 * i + 4].copy_from_slice(&v.to_le_bytes());
    }
    bytes
}

/// EXR files of every compression the `exr` crate writes, with f16 and f32 channels,
/// scan lines and tiles: the fuzzer's seeds for the decoders (B44 among them).
pub fn exr_variants() -> Vec<Vec<u8>> {
    use exr::prelude::*;
    // Large enough that B44 and the others compress (a block that does not shrink is stored
    // raw, which would leave their decoders unexercised).
    let (w, h) = (40usize, 36usize);
    let mut out = Vec::new();
    let compressions = [
        Compression::Uncompressed,
        Compression::RLE,
        Compression::ZIP1,
        Compression::ZIP16,
        Compression::PIZ,
        Compression::PXR24,
        Compression::B44,
        Compression::B44A,
    ];
    for (i, compression) in compressions.into_iter().enumerate() {
        let blocks = if i % 2 == 0 {
            Blocks::ScanLines
        } else {
            Blocks::Tiles(Vec2(8, 8))
        };
        let encoding = Encoding {
            compression,
            blocks,
            line_order: LineOrder::Increasing,
        };
        let pixel = |p: Vec2<usize>| {
            let v = (p.x() * 7 + p.y() * 3) as f32 / 40.0;
            (f16::from_f32(v), f16::from_f32(1.0 - v), f16::from_f32(0.5))
        };
        let layer = Layer::new(
            (w, h),
            LayerAttributes::named("main"),
            encoding,
            SpecificChannels::rgb(pixel),
        );
        let mut bytes = Vec::new();
        if exr::image::Image::from_layer(layer)
            .write()
            .to_buffered(Cursor::new(&mut bytes))
            .is_ok()
        {
            out.push(bytes);
        }
    }
    out
}

/// A 32 x 32 B44 EXR of a smooth gradient whose first compressed 4 x 4 block is all zero
/// bytes: the `exr` crate's B44 decoder (1.74) subtracts the block's bias from a zero base
/// value, an arithmetic overflow that panics in builds with overflow checks. Decoded on a
/// rayon thread (the crate's parallel path) that panic aborts the process.
pub fn exr_b44_overflow() -> Vec<u8> {
    use exr::prelude::*;
    let encoding = Encoding {
        compression: Compression::B44,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let pixel = |p: Vec2<usize>| {
        let v = f16::from_f32(0.5 + (p.x() + p.y()) as f32 / 64.0);
        (v, v, v)
    };
    let layer = Layer::new(
        (32, 32),
        LayerAttributes::named("main"),
        encoding,
        SpecificChannels::rgb(pixel),
    );
    let mut bytes = Vec::new();
    exr::image::Image::from_layer(layer)
        .write()
        .to_buffered(Cursor::new(&mut bytes))
        .expect("write a B44 EXR");
    // Walk the header's attributes (name\0 type\0 size value) to its end, then follow the
    // first entry of the offset table to the first chunk: y (i32), size (i32), data.
    let mut at = 8;
    loop {
        let name_end = at + bytes[at..].iter().position(|&b| b == 0).expect("name");
        if name_end == at {
            at += 1;
            break;
        }
        let type_end = name_end
            + 1
            + bytes[name_end + 1..]
                .iter()
                .position(|&b| b == 0)
                .expect("type");
        let size = i32::from_le_bytes(bytes[type_end + 1..type_end + 5].try_into().unwrap());
        at = type_end + 5 + size as usize;
    }
    let chunk = u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
    let size = i32::from_le_bytes(bytes[chunk + 4..chunk + 8].try_into().unwrap()) as usize;
    assert!(
        (14..32 * 32 * 6).contains(&size),
        "the chunk is B44-compressed ({size} bytes)"
    );
    bytes[chunk + 8..chunk + 8 + 14].fill(0);
    bytes
}

/// Camera lists with values that JSON holds but an f32 camera cannot: a far plane that
/// becomes infinite, a field of view that becomes 0, NaN-like strings, huge positions, and
/// fields outside the scene contract's ranges (planes too far apart, too wide a view).
pub fn bad_camera_lists() -> Vec<(&'static str, String)> {
    let cam = |extra: &str| {
        format!(
            "[{{\"position\": [0.278, 0.273, -0.8], \"target\": [0.278, 0.273, 0], \"fov\": 40{extra}}}]"
        )
    };
    vec![
        ("far 1e39 (infinite as f32)", cam(", \"far\": 1e39")),
        (
            "fov 1e-45 (0 radians as f32)",
            cam("").replace("\"fov\": 40", "\"fov\": 1e-45"),
        ),
        ("near 0", cam(", \"near\": 0")),
        ("near above far", cam(", \"near\": 2, \"far\": 1")),
        (
            "position 1e39",
            cam("").replace("[0.278, 0.273, -0.8]", "[1e39, 0, 0]"),
        ),
        (
            "far / near 1e9 (f32 depth cannot separate them)",
            cam(", \"near\": 1e-9, \"far\": 1"),
        ),
        (
            "fov 179 (wider than 170 degrees)",
            cam("").replace("\"fov\": 40", "\"fov\": 179"),
        ),
    ]
}

/// Writes `bytes` to `dir/name` and returns the path.
pub fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).expect("write a hostile file");
    p
}

/// The Cornell box with the material features import reads beyond colour: its first mesh
/// alpha-masked by an RGBA texture (nearest, clamped), its vertices coloured, and an
/// emitting quad whose emission is a texture: a seed whose mutations reach those readers.
pub fn material_features() -> scene_core::Scene {
    use scene_core::glam::Vec2;
    let mut s = builtin::scene("cornell").expect("built-in scene");
    let n = 4usize;
    s.textures.push(scene_core::Texture {
        name: "mask".into(),
        width: n as u32,
        height: n as u32,
        texels: vec![Vec3::new(0.8, 0.6, 0.4); n * n],
        alpha: Some((0..n * n).map(|i| ((i + i / n) % 2) as f32).collect()),
        sampler: scene_core::Sampler {
            wrap_u: scene_core::Wrap::ClampToEdge,
            wrap_v: scene_core::Wrap::MirroredRepeat,
            nearest: true,
        },
    });
    s.textures.push(scene_core::Texture {
        name: "glow".into(),
        width: 2,
        height: 1,
        texels: vec![Vec3::ONE, Vec3::splat(0.25)],
        alpha: None,
        sampler: Default::default(),
    });
    let first = s.meshes[0].material_ids[0] as usize;
    s.materials[first].albedo_texture = Some(0);
    s.materials[first].alpha_cutoff = Some(0.5);
    for m in &mut s.meshes {
        m.uvs = Some(
            m.positions
                .iter()
                .map(|p| Vec2::new(p.x, p.z) * 3.0)
                .collect(),
        );
        m.colors = Some(
            m.positions
                .iter()
                .map(|p| (p.abs() * 2.0).fract())
                .collect(),
        );
    }
    if let Some(lamp) = s.materials.iter_mut().find(|m| m.is_emissive()) {
        lamp.emission_texture = Some(1);
    }
    s.validate().expect("the feature scene is valid");
    s
}
