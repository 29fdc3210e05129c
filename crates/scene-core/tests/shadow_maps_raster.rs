//! The orthographic shadow maps (suns, the sky's directions) are rasterised on the CPU
//! (`esm::raster_ortho`); their reference is the ray cast they replaced, a ray per texel
//! through the BVH (`esm::render_ortho`). Over the Cornell box with an alpha-masked quad,
//! for overhead, slanted and grazing directions, in metres, millimetres and a kilometre
//! from the origin, the two maps agree at every texel but the few a triangle's edge passes
//! within rounding of, and the depths they share agree to float rounding.

use glam::{Vec2, Vec3};
use scene_core::cutout::Cutouts;
use scene_core::ray::RayScene;
use scene_core::shadowed_lights::esm::{MapKind, raster_ortho, render_ortho};
use scene_core::{Material, Mesh, Sampler, Scene, Texture, View, builtin};

/// The Cornell box with a slanted quad whose 8x8 checker mask cuts half of it away.
fn masked_cornell() -> Scene {
    let mut s = builtin::cornell();
    let checker = |i: u32| ((i % 8) / 2 + (i / 8) / 2) % 2;
    s.textures.push(Texture {
        name: "mask".into(),
        width: 8,
        height: 8,
        texels: vec![Vec3::splat(0.8); 64],
        alpha: Some((0..64).map(|i| (checker(i) == 0) as u8 as f32).collect()),
        sampler: Sampler {
            nearest: true,
            ..Default::default()
        },
    });
    let masked = s.materials.len() as u32;
    s.materials.push(Material {
        albedo_texture: Some(s.textures.len() as u32 - 1),
        alpha_cutoff: Some(0.5),
        ..Material::diffuse("masked", Vec3::splat(0.9))
    });
    let mut quad = Mesh {
        name: "masked quad".into(),
        uvs: Some(Vec::new()),
        ..Default::default()
    };
    quad.push_quad(
        [
            Vec3::new(0.1, 0.3, 0.2),
            Vec3::new(0.45, 0.3, 0.2),
            Vec3::new(0.45, 0.45, 0.35),
            Vec3::new(0.1, 0.45, 0.35),
        ],
        masked,
    );
    for uv in quad.uvs.as_mut().unwrap() {
        *uv = *uv * 2.5 - Vec2::splat(0.3);
    }
    s.meshes.push(quad);
    s.validate().unwrap();
    s
}

/// Between the raster and the ray cast of `scene` along `direction` at `res` texels: the
/// texels either map hits, those where they differ (one hits and the other misses, or the
/// depths are more than `tolerance` extents apart), and the largest depth difference over
/// the texels both hit within tolerance.
fn compare(scene: &Scene, direction: Vec3, res: u32, tolerance: f32) -> (usize, usize, f32) {
    let extent = scene.extent();
    let half = 0.5 * extent;
    let b = scene.bounds();
    let view = View::orthographic_fit(b.center(), direction, half);
    let kind = MapKind::Ortho {
        eye: view.eye,
        right: view.right(),
        up: view.up,
        forward: view.forward,
        half_extent: half,
    };
    let rays = RayScene::build(scene);
    let cast = render_ortho(&rays, &kind, res, extent);
    let raster = raster_ortho(
        &scene.triangle_corners(),
        &Cutouts::of(scene),
        &kind,
        res,
        extent,
    );
    assert_eq!(cast.len(), raster.len());
    let miss = 4.0 * half / extent;
    let (mut hits, mut differ, mut worst) = (0, 0, 0.0f32);
    for (a, b) in cast.iter().zip(&raster) {
        assert!(a.is_finite() && b.is_finite());
        let (ha, hb) = (*a < miss, *b < miss);
        hits += (ha || hb) as usize;
        if ha != hb || (a - b).abs() > tolerance {
            differ += 1;
        } else {
            worst = worst.max((a - b).abs());
        }
    }
    (hits, differ, worst)
}

#[test]
fn rasterised_orthographic_maps_equal_the_ray_cast() {
    let base = masked_cornell();
    let res = 256;
    for (label, scene) in [
        ("metres", base.clone()),
        ("millimetres", base.clone().scaled(1e-3)),
        (
            "a kilometre away",
            base.translated(Vec3::new(1e3, -400.0, 700.0)),
        ),
    ] {
        for direction in [
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(-0.3, -1.0, -0.2),
            Vec3::new(0.6, -0.5, 0.9),
            // Grazing the floor and the back wall.
            Vec3::new(1.0, -0.02, 0.05),
            Vec3::new(0.0, 0.0, 1.0),
        ] {
            // Float rounding of the depth: relative to the extent, or to the coordinates
            // a kilometre from a metre-wide room.
            let tolerance = if label == "a kilometre away" {
                2e-3
            } else {
                1e-5
            };
            let (hits, differ, worst) = compare(&scene, direction, res, tolerance);
            let texels = (res * res) as usize;
            eprintln!(
                "{label}, {direction}: {hits} texels hit, {differ} differ, largest depth \
                 difference elsewhere {worst:.2e} extents"
            );
            assert!(hits > texels / 4, "{label} {direction}: {hits} hits");
            // Texels whose centre lies within rounding of an edge; a mask's cut or a
            // missing triangle would be thousands.
            assert!(
                differ * 1000 <= texels,
                "{label} {direction}: {differ} texels differ"
            );
        }
    }
}
