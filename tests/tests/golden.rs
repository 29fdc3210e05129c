//! Golden tests across the pipeline: glTF export and import feed the reference path tracer
//! the same scene; EXR output reads back exactly.

use scene_core::reference::{Bounces, ReferenceSettings, render};
use scene_core::{Image, View, builtin, gltf_io};

fn temp(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("golden-{}-{name}", std::process::id()))
}

#[test]
fn exported_builtins_render_identically_after_reimport() {
    for name in ["cornell", "cornell-point", "primitives", "corridor"] {
        let scene = builtin::scene(name).unwrap();
        let path = temp(&format!("{name}.glb"));
        gltf_io::export(&scene, &path).unwrap();
        let back = gltf_io::import(&path).unwrap().scene;
        std::fs::remove_file(&path).ok();
        let settings = ReferenceSettings {
            width: 24,
            height: 18,
            spp: 4,
            bounces: Bounces::Limited(1),
            seed: 5,
        };
        let cam = scene.cameras[0].with_aspect(24.0 / 18.0);
        let a = render(&scene, &View::from_camera(&cam), &settings, None).image;
        let cam_back = back.cameras[0].with_aspect(24.0 / 18.0);
        let b = render(&back, &View::from_camera(&cam_back), &settings, None).image;
        // Positions and camera survive to float precision; the images agree to the last few
        // ulps where a ray's path is not changed by a rounding difference.
        let close = a
            .pixels
            .iter()
            .zip(&b.pixels)
            .filter(|(p, q)| (**p - **q).abs().max_element() <= 1e-4 * p.max_element().max(1e-3))
            .count();
        assert!(
            close as f64 >= 0.98 * a.pixels.len() as f64,
            "{name}: only {close} of {} pixels agree",
            a.pixels.len()
        );
        assert!(
            a.mean()
                .abs_diff_eq(b.mean(), 0.02 * a.mean().max_element()),
            "{name}: {} vs {}",
            a.mean(),
            b.mean()
        );
    }
}

#[test]
fn reference_exr_round_trips_bit_exact() {
    let scene = builtin::scene("cornell").unwrap();
    let settings = ReferenceSettings {
        width: 20,
        height: 20,
        spp: 2,
        bounces: Bounces::Unlimited,
        seed: 1,
    };
    let out = render(
        &scene,
        &View::from_camera(&scene.cameras[0]),
        &settings,
        None,
    );
    let path = temp("cornell.exr");
    out.image.write_exr(&path).unwrap();
    let back = Image::read_exr(&path).unwrap();
    std::fs::remove_file(&path).ok();
    assert_eq!(back, out.image);
}
