//! No light leaks: two closed rooms side by side, sharing a wall 1 % of the room thick, a
//! point light in one. The other room stays dark (below 1e-4 of the lit room's mean) with
//! both form-factor methods and the hierarchical solve, the ambient term on.

use std::sync::Arc;

use glam::Vec3;
use relight_pr::{FormFactorMethod, MeshSettings, Meshing, SolverSettings, relight, solve_with};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::lights::LightState;
use scene_core::ray::RayScene;
use scene_core::{Material, Mesh, PointLight, Scene};

/// A closed box `[lo, hi]` with inward faces (counter-clockwise seen from inside).
fn room(mesh: &mut Mesh, lo: Vec3, hi: Vec3) {
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let (a, b) = (lo, hi);
    for q in [
        [
            v(a.x, a.y, a.z),
            v(a.x, a.y, b.z),
            v(b.x, a.y, b.z),
            v(b.x, a.y, a.z),
        ],
        [
            v(a.x, b.y, a.z),
            v(b.x, b.y, a.z),
            v(b.x, b.y, b.z),
            v(a.x, b.y, b.z),
        ],
        [
            v(a.x, a.y, a.z),
            v(b.x, a.y, a.z),
            v(b.x, b.y, a.z),
            v(a.x, b.y, a.z),
        ],
        [
            v(a.x, a.y, b.z),
            v(a.x, b.y, b.z),
            v(b.x, b.y, b.z),
            v(b.x, a.y, b.z),
        ],
        [
            v(a.x, a.y, a.z),
            v(a.x, b.y, a.z),
            v(a.x, b.y, b.z),
            v(a.x, a.y, b.z),
        ],
        [
            v(b.x, a.y, a.z),
            v(b.x, a.y, b.z),
            v(b.x, b.y, b.z),
            v(b.x, b.y, a.z),
        ],
    ] {
        mesh.push_quad(q, 0);
    }
}

fn two_rooms() -> Scene {
    two_rooms_to(2.01)
}

/// The two rooms, the second one reaching `right` along x.
fn two_rooms_to(right: f32) -> Scene {
    let mut scene = Scene::new("two rooms");
    scene.materials.push(Material {
        name: "white".into(),
        albedo: Vec3::splat(0.8),
        albedo_texture: None,
        emission: Vec3::ZERO,
        alpha_cutoff: None,
        emission_texture: None,
    });
    let mut mesh = Mesh {
        name: "rooms".into(),
        ..Default::default()
    };
    room(&mut mesh, Vec3::ZERO, Vec3::ONE);
    // The wall between them: x from 1 to 1.01.
    room(
        &mut mesh,
        Vec3::new(1.01, 0.0, 0.0),
        Vec3::new(right, 1.0, 1.0),
    );
    scene.meshes.push(mesh);
    scene.point_lights.push(PointLight {
        name: "lamp".into(),
        // Close to the shared wall, where a leak would show first.
        position: Vec3::new(0.9, 0.5, 0.5),
        intensity: Vec3::splat(1.0),
        radius: None,
        cone: None,
    });
    scene
}

#[test]
fn the_dark_room_stays_dark_with_both_form_factor_methods() {
    let scene = Arc::new(two_rooms());
    let meshing = Meshing::new(&scene, &MeshSettings::elements(768), 1).unwrap();
    let rays = RayScene::build(&scene);
    for (method, hierarchy) in [
        (FormFactorMethod::Rays, None),
        (FormFactorMethod::Hemicube { resolution: 64 }, None),
        (
            FormFactorMethod::Rays,
            Some(relight_pr::HierarchySettings {
                tolerance: 1e-2,
                ..Default::default()
            }),
        ),
    ] {
        let settings = SolverSettings {
            form_factors: method,
            max_unshot: 1e-2,
            visibility_samples: 8,
            hierarchy,
            hierarchy_above: 0,
            ..Default::default()
        };
        let mut renderer = RayCastRenderer::new();
        let solution = solve_with(
            &scene,
            &meshing,
            &rays,
            Some(&mut renderer),
            &settings,
            &mut |_| {},
        )
        .unwrap();
        assert!(
            solution.ambient[0].max_element() > 0.0,
            "the ambient term is on"
        );
        let radiance = relight::radiance(&meshing, &solution, &LightState::default());
        let (mut lit, mut dark) = ((0.0f64, 0.0f64), (0.0f64, 0.0f64));
        for (e, r) in meshing.elements.iter().zip(&radiance) {
            let side = if e.centroid.x < 1.005 {
                &mut lit
            } else {
                &mut dark
            };
            side.0 += (r.element_sum() * e.area) as f64;
            side.1 += e.area as f64;
        }
        let (lit, dark) = (lit.0 / lit.1, dark.0 / dark.1);
        let method = (method, hierarchy.is_some());
        eprintln!("{method:?}: lit room mean {lit:.4e}, dark room mean {dark:.3e}");
        assert!(lit > 0.0);
        assert!(dark < 1e-4 * lit, "{method:?}: {dark} against {lit}");
    }
}

/// The two rooms standing on one floor that runs under the shared wall (the floor's
/// elements straddle the wall unless the meshing splits them), the wall a closed slab. The
/// second room is longer, so that the floor's subdivision lines do not fall inside the
/// wall.
fn rooms_on_one_floor() -> Scene {
    let right = 2.5;
    let mut scene = two_rooms_to(right);
    let mesh = &mut scene.meshes[0];
    // Drop both rooms' floors (the first face of each room: two triangles each).
    let keep: Vec<usize> = (0..mesh.indices.len())
        .filter(|&t| {
            let y = mesh.indices[t].map(|i| mesh.positions[i as usize].y);
            !(y.iter().all(|&v| v == 0.0))
        })
        .collect();
    mesh.indices = keep.iter().map(|&t| mesh.indices[t]).collect();
    mesh.material_ids = keep.iter().map(|&t| mesh.material_ids[t]).collect();
    // Close the slab between the rooms (x from 1 to 1.01): a top and two ends, facing out.
    let (x0, x1) = (1.0, 1.01);
    mesh.push_quad(
        [
            Vec3::new(x0, 1.0, 0.0),
            Vec3::new(x0, 1.0, 1.0),
            Vec3::new(x1, 1.0, 1.0),
            Vec3::new(x1, 1.0, 0.0),
        ],
        0,
    );
    mesh.push_quad(
        [
            Vec3::new(x0, 0.0, 0.0),
            Vec3::new(x0, 1.0, 0.0),
            Vec3::new(x1, 1.0, 0.0),
            Vec3::new(x1, 0.0, 0.0),
        ],
        0,
    );
    mesh.push_quad(
        [
            Vec3::new(x0, 0.0, 1.0),
            Vec3::new(x1, 0.0, 1.0),
            Vec3::new(x1, 1.0, 1.0),
            Vec3::new(x0, 1.0, 1.0),
        ],
        0,
    );
    // One floor under both, facing up.
    mesh.push_quad(
        [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(right, 0.0, 1.0),
            Vec3::new(right, 0.0, 0.0),
        ],
        0,
    );
    scene
}

/// The mean of an image over its non-black pixels' count (all pixels see surfaces here).
fn image_mean(img: &scene_core::Image) -> f64 {
    img.pixels
        .iter()
        .map(|p| p.element_sum() as f64)
        .sum::<f64>()
        / img.pixels.len() as f64
}

#[test]
fn a_floor_running_under_the_wall_does_not_carry_light_through_it() {
    use relight_pr::RelightTechnique;
    use scene_core::{Camera, FrameRequest, Technique};
    let scene = Arc::new(rooms_on_one_floor());
    // Cameras in each room looking down at the floor along the wall.
    let camera = |x: f32, towards: f32| Camera {
        name: "floor".into(),
        position: Vec3::new(x, 0.6, 0.5),
        target: Vec3::new(towards, 0.0, 0.5),
        up: Vec3::Y,
        fov_y: 0.9,
        aspect: 1.0,
        near: 1e-3,
        far: 10.0,
    };
    let (lit_camera, dark_camera) = (camera(0.6, 0.98), camera(1.41, 1.03));
    let mut leaks = Vec::new();
    let hierarchical = Some(relight_pr::HierarchySettings {
        tolerance: 1e-2,
        ..Default::default()
    });
    let between_groups = Some(relight_pr::HierarchySettings {
        tolerance: 1e-2,
        solve_groups_above: 0.0,
        ..Default::default()
    });
    // The first three hold one value per mesh element (the splits are what they test);
    // the last three hold the element budget, whose groups must not reach across the wall
    // (the last solved between the groups).
    let cases = [
        (0, None, false),
        (6, None, false),
        (6, hierarchical, false),
        (6, None, true),
        (6, hierarchical, true),
        (6, between_groups, true),
    ];
    for (split_depth, hierarchy, hold_budget) in cases {
        let mut t = RelightTechnique::new(
            MeshSettings {
                split_depth,
                hold_budget,
                ..MeshSettings::elements(768)
            },
            SolverSettings {
                max_unshot: 1e-2,
                visibility_samples: 8,
                hierarchy,
                hierarchy_above: 0,
                ..Default::default()
            },
            Box::new(RayCastRenderer::new()),
        );
        t.prepare(scene.clone()).unwrap();
        let p = t.prepared().unwrap();
        let radiance = relight::radiance(&p.meshing, &p.solution, &LightState::default());
        let (mut lit, mut dark) = ((0.0f64, 0.0f64), (0.0f64, 0.0f64));
        for (e, r) in p.meshing.elements.iter().zip(&radiance) {
            if e.centroid.x < 1.0 {
                lit.0 += (r.element_sum() * e.area) as f64;
                lit.1 += e.area as f64;
            } else if e.centroid.x > 1.01 {
                dark.0 += (r.element_sum() * e.area) as f64;
                dark.1 += e.area as f64;
            }
        }
        let (lit, dark) = (lit.0 / lit.1, dark.0 / dark.1);
        let (elements, splits, groups) = (
            p.meshing.elements.len(),
            p.meshing.split_patches,
            p.meshing.groups.count,
        );
        let state = LightState::default();
        let mut images = Vec::new();
        for direct in [
            relight_pr::direct::DirectLight::Elements,
            relight_pr::direct::DirectLight::default(),
        ] {
            t.direct = direct;
            let lit_img = t
                .render(&FrameRequest::from_camera(&lit_camera, 32, 32, &state))
                .unwrap();
            let dark_img = t
                .render(&FrameRequest::from_camera(&dark_camera, 32, 32, &state))
                .unwrap();
            images.push((image_mean(&lit_img), image_mean(&dark_img)));
        }
        eprintln!(
            "split depth {split_depth}, hierarchical {}: {elements} elements in {} groups \
             ({splits} patches split); elements: lit {lit:.4e}, dark {dark:.3e}; images \
             (elements, per-pixel direct): {images:?}",
            hierarchy.is_some(),
            groups
        );
        leaks.push((dark / lit, images));
    }
    // Without splitting, the floor's elements under the wall carry light into the dark
    // room's image (the case this test is about); with it, nothing reaches it.
    let unsplit = &leaks[0].1;
    assert!(
        unsplit.iter().all(|(lit, dark)| *dark > 1e-3 * lit),
        "the unsplit floor leaks: {unsplit:?}"
    );
    for (elements, images) in &leaks[1..] {
        assert!(*elements < 1e-4, "elements: {elements}");
        for (lit, dark) in images {
            assert!(*lit > 0.0);
            assert!(*dark < 1e-4 * lit, "display: dark {dark} against lit {lit}");
        }
    }
    // Grouped, the dark room's elements hold what the same solve gave them one by one (a
    // group reaching under the wall would average the lit floor into them: 5x more, with
    // groups cut by size alone and no parting by sight).
    for (grouped, single) in [(3, 1), (4, 2)] {
        let (g, s) = (leaks[grouped].0, leaks[single].0);
        assert!(g <= s * 1.01 + 1e-9, "grouped {g} against one by one {s}");
    }
}

/// The splits at walls stop at a size relative to the target, not to each triangle: a
/// small tile lying on the floor across the wall is split while its pieces are larger than
/// the target's patch area over `4^split_depth`, and no further (counted from the tile's
/// own size, its pieces went down to 1 cm, where they stop straddling the slab, far below
/// the element size asked for); the floor under the wall still splits.
#[test]
fn splits_at_walls_stop_at_a_size_set_by_the_target() {
    let mut scene = rooms_on_one_floor();
    // A 4 cm tile 1 mm above the floor, crossing the 1 cm slab at x = 1.
    let y = 0.001;
    scene.meshes[0].push_quad(
        [
            Vec3::new(0.98, y, 0.48),
            Vec3::new(0.98, y, 0.52),
            Vec3::new(1.02, y, 0.52),
            Vec3::new(1.02, y, 0.48),
        ],
        0,
    );
    scene.validate().unwrap();
    // A coarse target: its finest split (patches of about 2.7 cm) is larger than the
    // pieces the tile would reach if counted from its own size (1 cm, where its pieces stop
    // straddling the 1 cm slab).
    let settings = MeshSettings {
        merge_coplanar: false,
        ..MeshSettings::elements(16)
    };
    let m = Meshing::new(&scene, &settings, 1).unwrap();
    let finest = m.patch_area / 4f32.powi(settings.split_depth as i32);
    let tile: Vec<f32> = m
        .elements
        .iter()
        .filter(|e| (e.centroid.y - y).abs() < 1e-5)
        .map(|e| e.area)
        .collect();
    let tile_area = 0.04 * 0.04;
    assert!(!tile.is_empty());
    assert!(
        (tile.iter().sum::<f32>() - tile_area).abs() < 1e-3 * tile_area,
        "{tile:?}"
    );
    // Its pieces stay above a quarter of the finest size (a split quarters a patch larger
    // than it), or whole: its two triangles, smaller than that, are not split at all.
    let smallest = tile.iter().copied().fold(f32::MAX, f32::min);
    let bound = (0.25 * finest).min(0.5 * tile_area);
    assert!(
        smallest >= bound * (1.0 - 1e-3),
        "smallest piece {smallest}, finest patch {finest}, {} pieces",
        tile.len()
    );
    assert!(m.split_patches > 0);
}
