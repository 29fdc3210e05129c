//! Hard cases: empty and unlit scenes, scale, contact, thin geometry, many surfaces in one
//! pixel's frustum, surfaces no IRPL reached.

mod common;

use std::sync::Arc;

use common::{errors, mean};
use glam::Vec3;
use ibrr_ldc::{IbrrSettings, IbrrTechnique};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::{
    Camera, FrameRequest, Image, Material, Mesh, PointLight, Scene, Technique, builtin,
};

fn small() -> IbrrSettings {
    IbrrSettings {
        target_error: 0.0,
        resolution: 64,
        irpls: 24,
        ..Default::default()
    }
}

fn render(
    scene: &Arc<Scene>,
    settings: IbrrSettings,
    camera: &Camera,
    size: u32,
) -> (Image, IbrrTechnique) {
    let mut t = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
    t.prepare(scene.clone()).unwrap();
    let img = t.render(&FrameRequest::camera(camera, size, size)).unwrap();
    (img, t)
}

fn finite(img: &Image) -> bool {
    img.pixels
        .iter()
        .all(|p| p.is_finite() && p.min_element() >= 0.0)
}

#[test]
fn an_empty_scene_is_refused_and_a_scene_without_lights_is_black() {
    let camera = builtin::scene("cornell").unwrap().cameras[0].clone();
    // An empty scene is refused naming the fault (the scene contract), nothing built.
    let empty = Arc::new(Scene::new("empty"));
    let mut t = IbrrTechnique::new(small(), Box::new(RayCastRenderer::new()));
    let e = t.prepare(empty).unwrap_err();
    assert!(
        matches!(
            e,
            scene_core::Error::Scene(scene_core::SceneError::NoGeometry { .. })
        ),
        "{e}"
    );
    assert!(t.ldc().is_none());
    let mut dark = builtin::scene("cornell-point").unwrap();
    dark.point_lights.clear();
    let dark = Arc::new(dark);
    let (img, t) = render(&dark, small(), &camera, 16);
    assert!(
        img.pixels.iter().all(|p| *p == Vec3::ZERO),
        "no light, no radiance"
    );
    assert_eq!(t.construction().unwrap().irpls.irpls.len(), 0);
}

#[test]
fn scaled_scenes_give_the_same_picture() {
    let base = builtin::scene("cornell-point").unwrap();
    let camera = base.cameras[0].clone();
    let (reference, _) = render(&Arc::new(base.clone()), small(), &camera, 32);
    for k in [1e-3f32, 1e4] {
        let scaled = base.clone().scaled(k);
        let cam = scaled.cameras[0].clone();
        let (img, t) = render(&Arc::new(scaled), small(), &cam, 32);
        assert!(finite(&img));
        let (mae, bias) = errors(&img, &reference);
        println!(
            "x{k}: mae {mae:.2e}, bias {bias:.2e}, missing {}",
            t.last_timings().missing
        );
        // The LDC follows the scene's extent; only f32 rounding of the scaled geometry
        // differs (a few visibility and plane decisions at edges).
        assert!(
            mae < 0.01 && bias.abs() < 0.005,
            "x{k}: mae {mae}, bias {bias}"
        );
    }
}

/// Cornell-point with extra geometry: a slab 0.5% of the room thick floating under the
/// light, and a comb of 40 thin slats far from the light (several surfaces in one hemicube
/// pixel's frustum, section 6.1).
fn cluttered() -> Scene {
    let mut s = builtin::scene("cornell-point").unwrap();
    let extent = s.extent();
    let mat = s.materials.len() as u32;
    s.materials
        .push(Material::diffuse("clutter", Vec3::splat(0.6)));
    let mut m = Mesh {
        name: "clutter".into(),
        ..Default::default()
    };
    let b = s.bounds();
    let c = b.center();
    let size = b.max - b.min;
    m.push_box(
        Vec3::new(c.x, b.min.y + 0.6 * size.y, c.z),
        Vec3::new(0.15 * size.x, 0.0025 * extent, 0.15 * size.z),
        0.0,
        mat,
    );
    for i in 0..40 {
        let x = b.min.x + size.x * (0.1 + 0.8 * i as f32 / 40.0);
        m.push_box(
            Vec3::new(x, b.min.y + 0.05 * size.y, b.min.z + 0.1 * size.z),
            Vec3::new(0.002 * size.x, 0.05 * size.y, 0.05 * size.z),
            0.3,
            mat,
        );
    }
    s.meshes.push(m);
    s.validate().unwrap();
    s
}

#[test]
fn thin_geometry_contact_and_crowded_pixels_stay_finite_and_shadowed() {
    let scene = Arc::new(cluttered());
    let camera = scene.cameras[0].clone();
    // Enough IRPLs that some bounce's render sees the slab's underside and founds its
    // layers (with 24, whether one does is the walks' luck).
    let settings = IbrrSettings {
        irpls: 96,
        ..small()
    };
    let (img, t) = render(&scene, settings, &camera, 48);
    assert!(finite(&img));
    assert!(mean(&img) > 0.0);
    // The slab's underside gets no direct light from the point light above it.
    let ldc = t.ldc().unwrap();
    let b = scene.bounds();
    let c = b.center();
    let y = b.min.y + 0.6 * (b.max.y - b.min.y) - 0.0025 * scene.extent();
    let under = ibrr_ldc::lookup(
        ldc,
        Vec3::new(c.x, y, c.z),
        -Vec3::Y,
        ibrr_ldc::Lookup::Nearest,
        0,
    );
    let top = ibrr_ldc::lookup(
        ldc,
        Vec3::new(c.x, y + 0.005 * scene.extent(), c.z),
        Vec3::Y,
        ibrr_ldc::Lookup::Nearest,
        0,
    );
    let (under, top) = (
        under.expect("the underside is seen by bounces"),
        top.expect("the top is lit"),
    );
    assert_eq!(under.0, Vec3::ZERO, "direct light under the slab");
    assert!(top.0.min_element() > 0.0, "direct light on top of the slab");
    // Every IRPL sits on a surface with a finite power, including those on the boxes
    // touching the floor (r -> 0 at the contact).
    for irpl in &t.construction().unwrap().irpls.irpls {
        assert!(irpl.power.is_finite() && irpl.position.is_finite());
    }
    assert!(
        ldc.direct
            .iter()
            .chain(&ldc.indirect)
            .all(|v| v.is_finite())
    );
}

#[test]
fn surfaces_no_irpl_reached_are_black_and_counted() {
    // A closed lit box seen from outside: no IRPL reaches its outer faces.
    let mut s = Scene::new("closed box");
    s.materials
        .push(Material::diffuse("white", Vec3::splat(0.7)));
    let mut m = Mesh {
        name: "box".into(),
        ..Default::default()
    };
    m.push_box(Vec3::ZERO, Vec3::ONE, 0.0, 0);
    s.meshes.push(m);
    s.point_lights.push(PointLight {
        name: "inside".into(),
        position: Vec3::ZERO,
        intensity: Vec3::ONE,
        radius: None,
        cone: None,
    });
    s.validate().unwrap();
    let scene = Arc::new(s);
    let camera = Camera {
        name: "outside".into(),
        position: Vec3::new(3.0, 2.0, 4.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y: 0.8,
        aspect: 1.0,
        near: 0.01,
        far: 20.0,
    };
    let (img, t) = render(&scene, small(), &camera, 32);
    assert!(img.pixels.iter().all(|p| *p == Vec3::ZERO));
    let seen = t.last_timings().missing;
    assert!(seen > 100, "{seen} pixels of the box counted as missing");
    assert!(t.ldc().unwrap().layer_count() > 0, "the inside was built");
}
