//! Renders a built-in scene (or a glTF file) with the reference path tracer and writes an EXR
//! and a PNG preview.
//!
//! ```sh
//! cargo run --release -p scene-core --example quick_reference -- cornell 128 64 out.png
//! ```

use scene_core::reference::{Bounces, ReferenceSettings, render};
use scene_core::{View, builtin, gltf_io};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map(String::as_str).unwrap_or("cornell");
    let size: u32 = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(128);
    let spp: u32 = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(64);
    let out = args
        .get(3)
        .map(String::as_str)
        .unwrap_or("quick_reference.png");

    let scene = if name.ends_with(".gltf") || name.ends_with(".glb") {
        gltf_io::import(name.as_ref())?.scene
    } else {
        builtin::scene(name)?
    };
    let camera = scene.cameras.first().ok_or("the scene has no camera")?;
    let view = View::from_camera(&camera.with_aspect(1.0));
    let settings = ReferenceSettings {
        width: size,
        height: size,
        spp,
        bounces: Bounces::Unlimited,
        seed: 1,
    };
    let result = render(&scene, &view, &settings, None);
    result.image.write_png(out.as_ref(), 0.0)?;
    result
        .image
        .write_exr(std::path::Path::new(out).with_extension("exr").as_path())?;
    println!(
        "{out}: {} rays in {:.2} s ({:.1} Mrays/s)",
        result.stats.total(),
        result.stats.seconds,
        result.stats.rays_per_second() / 1e6
    );
    Ok(())
}
