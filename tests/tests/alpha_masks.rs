//! Alpha-masked materials (glTF's `alphaMode: MASK`, `scene_core::Material::alpha_cutoff`)
//! in every place that decides visibility, against the opaque shape the mask draws: a grille
//! over the lit room is one quad whose texture's alpha is a 4 x 4 checkerboard (nearest
//! filter, so its solid squares have sharp edges), and its twin is the eight solid squares as
//! geometry. Rays, rasterised G-buffers (CPU and GPU) and shadow maps must see the same
//! holes; every method must render the masked grille as close to the reference as it
//! renders the twin, and much closer than it renders the grille with its mask ignored.

use std::sync::Arc;

use golden_tests::scenes::{self, relative_difference as rel, techniques};
use scene_core::glam::{Vec2, Vec3};
use scene_core::scene::{Material, Mesh, Sampler, Scene, Texture};
use scene_core::{GBufferRenderer, Image, Technique, View};

const W: u32 = 48;
const H: u32 = 36;
/// The grille's height and its square in x and z.
const Y: f32 = 0.35;
const LO: Vec2 = Vec2::new(0.1, 0.2);
const SIZE: f32 = 0.8;
const CELLS: u32 = 4;

/// The lit room (a point light) with the grille: `Masked` as one alpha-masked quad,
/// `Twin` as its solid squares, `Unmasked` as the quad with its mask ignored.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Grille {
    Masked,
    Twin,
    Unmasked,
}

fn solid(i: u32, j: u32) -> bool {
    (i + j).is_multiple_of(2)
}

fn room(grille: Grille) -> Scene {
    let mut s = scenes::lit_room(true, false);
    // Looking down on the grille over the red block, its shadow on the floor around.
    let camera = &mut s.cameras[0];
    camera.position = Vec3::new(0.5, 0.75, 1.15);
    camera.target = Vec3::new(0.5, 0.1, 0.45);
    let material = s.materials.len() as u32;
    let mut m = Material::diffuse("grille", Vec3::new(0.3, 0.5, 0.7));
    let mut mesh = Mesh {
        name: "grille".into(),
        ..Default::default()
    };
    let corner = |x: f32, z: f32| Vec3::new(x, Y, z);
    match grille {
        Grille::Twin => {
            let cell = SIZE / CELLS as f32;
            for i in 0..CELLS {
                for j in 0..CELLS {
                    if !solid(i, j) {
                        continue;
                    }
                    let (x, z) = (LO.x + i as f32 * cell, LO.y + j as f32 * cell);
                    mesh.push_quad_facing(
                        [
                            corner(x, z),
                            corner(x + cell, z),
                            corner(x + cell, z + cell),
                            corner(x, z + cell),
                        ],
                        material,
                        Vec3::new(0.5, 0.8, 0.6),
                    );
                }
            }
        }
        Grille::Masked | Grille::Unmasked => {
            // Texel (i, j) covers u in [i, i + 1) / CELLS (x) and v in [j, j + 1) / CELLS (z).
            let n = (CELLS * CELLS) as usize;
            let mut alpha = vec![0.0; n];
            for j in 0..CELLS {
                for i in 0..CELLS {
                    alpha[(j * CELLS + i) as usize] = if solid(i, j) { 1.0 } else { 0.0 };
                }
            }
            s.textures.push(Texture {
                name: "checker".into(),
                width: CELLS,
                height: CELLS,
                texels: vec![Vec3::ONE; n],
                alpha: Some(alpha),
                sampler: Sampler {
                    nearest: true,
                    ..Default::default()
                },
            });
            m.albedo_texture = Some(s.textures.len() as u32 - 1);
            if grille == Grille::Masked {
                m.alpha_cutoff = Some(0.5);
            }
            mesh.uvs = Some(Vec::new());
            mesh.push_quad_facing(
                [
                    corner(LO.x, LO.y),
                    corner(LO.x + SIZE, LO.y),
                    corner(LO.x + SIZE, LO.y + SIZE),
                    corner(LO.x, LO.y + SIZE),
                ],
                material,
                Vec3::new(0.5, 0.8, 0.6),
            );
            let uvs = mesh
                .positions
                .iter()
                .map(|p| (Vec2::new(p.x, p.z) - LO) / SIZE);
            mesh.uvs = Some(uvs.collect());
        }
    }
    s.materials.push(m);
    s.meshes.push(mesh);
    s.validate().expect("the grille room is valid");
    s
}

fn reference(scene: &Scene, seed: u64) -> Image {
    scenes::reference_image(scene, 512, seed, W, H)
}

fn render(t: &mut dyn Technique, scene: &Scene) -> Image {
    scenes::render_image(t, scene, W, H)
}

/// The grille's fixture is what it claims: the masked quad, its twin and the unmasked
/// quad differ as they should, seen straight down.
#[test]
fn rays_pass_through_the_holes_the_mask_draws() {
    let masked = room(Grille::Masked);
    let rays = scene_core::ray::RayScene::build(&masked);
    assert!(!rays.cutouts().is_empty());
    let cell = SIZE / CELLS as f32;
    for i in 0..CELLS {
        for j in 0..CELLS {
            let x = LO.x + (i as f32 + 0.5) * cell;
            let z = LO.y + (j as f32 + 0.5) * cell;
            let hit = rays
                .closest_hit(Vec3::new(x, 0.7, z), Vec3::NEG_Y, 0.0, 10.0)
                .expect("the floor or the grille");
            let at_grille = (hit.t - (0.7 - Y)).abs() < 1e-4;
            assert_eq!(at_grille, solid(i, j), "cell ({i}, {j}): t {}", hit.t);
            // Down to just under the grille (the red block's top lies 0.05 lower).
            let blocked = rays.occluded(Vec3::new(x, 0.7, z), Vec3::NEG_Y, 0.0, 0.7 - Y + 0.02);
            assert_eq!(blocked, solid(i, j), "cell ({i}, {j})");
            // The brute-force oracle agrees.
            let brute = scene_core::ray::brute_force_closest(
                &masked,
                Vec3::new(x, 0.7, z),
                Vec3::NEG_Y,
                0.0,
                10.0,
            )
            .unwrap();
            assert_eq!(brute.triangle, hit.triangle);
        }
    }
}

/// The G-buffers of the masked grille (CPU rasteriser, ray caster, GPU rasteriser) equal
/// those of its twin but at the squares' edges, where the texture's nearest lookup and the
/// twin's edges may round a pixel centre differently.
#[test]
fn gbuffers_show_the_twin_where_the_mask_cuts_holes() {
    let (masked, twin, unmasked) = (
        room(Grille::Masked),
        room(Grille::Twin),
        room(Grille::Unmasked),
    );
    let view = View::from_camera(&masked.cameras[0]);
    let (w, h) = (160, 120);
    let mut renderers: Vec<(&str, Box<dyn GBufferRenderer>)> = vec![
        ("cpu", Box::new(gbuffer::CpuRasterizer::new())),
        (
            "rays",
            Box::new(scene_core::gbuffer::RayCastRenderer::new()),
        ),
    ];
    if let Some(ctx) = scene_core::testing::gpu_test_context() {
        renderers.push(("gpu", Box::new(gbuffer::GpuRasterizer::new(&ctx).unwrap())));
    }
    for (name, mut r) in renderers {
        let mut gbuffer_of = |s: &Scene| {
            r.prepare(Arc::new(s.clone())).unwrap();
            r.render_view(&view, w, h).unwrap()
        };
        let (a, b, c) = (
            gbuffer_of(&masked),
            gbuffer_of(&twin),
            gbuffer_of(&unmasked),
        );
        let differ = |x: &scene_core::GBuffer, y: &scene_core::GBuffer| {
            x.depth
                .iter()
                .zip(&y.depth)
                .zip(x.albedo.iter().zip(&y.albedo))
                .filter(|((d0, d1), (a0, a1))| {
                    (*d0 - *d1).abs() > 1e-4 || (**a0 - **a1).abs().max_element() > 1e-4
                })
                .count() as f32
                / x.depth.len() as f32
        };
        let (to_twin, to_unmasked) = (differ(&a, &b), differ(&a, &c));
        eprintln!(
            "{name}: {:.2}% of pixels differ from the twin, {:.2}% from the unmasked quad",
            100.0 * to_twin,
            100.0 * to_unmasked
        );
        assert!(to_twin < 0.01, "{name}: {to_twin}");
        assert!(to_unmasked > 0.05, "{name}: {to_unmasked}");
    }
}

/// Every method renders the masked grille (its shadow, what shows through it, the light it
/// reflects) as close to the reference as it renders the twin, and its picture of the
/// masked grille is at least four times closer to its picture of the twin than its picture
/// of the grille with the mask ignored is.
#[test]
fn masked_surfaces_match_the_reference_in_every_method() {
    let (masked, twin, unmasked) = (
        room(Grille::Masked),
        room(Grille::Twin),
        room(Grille::Unmasked),
    );
    let ref_masked = reference(&masked, 5);
    let ref_twin = reference(&twin, 5);
    // The reference itself: the masked quad is its twin, within its noise.
    let noise = rel(&reference(&twin, 6), &ref_twin);
    let e_ref = rel(&ref_masked, &ref_twin);
    eprintln!("reference: masked vs twin {e_ref:.5} (two seeds differ by {noise:.5})");
    assert!(e_ref < 1.5 * noise, "{e_ref} vs noise {noise}");
    let ctx = scene_core::testing::gpu_test_context();
    // The scene contract's methods, and relighting with the paper's hemicube form factors
    // (its masked receivers see the hemicube through their solid part only).
    let methods = || {
        let mut m: Vec<(&str, Box<dyn Technique>)> = techniques(ctx.as_ref())
            .into_iter()
            .filter(|(name, _)| *name != "reference")
            .collect();
        m.push((
            "relight-hemicube",
            Box::new(relight_pr::RelightTechnique::new(
                relight_pr::MeshSettings::elements(64),
                relight_pr::SolverSettings {
                    form_factors: relight_pr::FormFactorMethod::Hemicube { resolution: 64 },
                    ..Default::default()
                },
                Box::new(gbuffer::CpuRasterizer::new()),
            )),
        ));
        m
    };
    let mut checked = 0;
    for (((name, mut t_masked), (_, mut t_twin)), (_, mut t_unmasked)) in
        methods().into_iter().zip(methods()).zip(methods())
    {
        let on_masked = render(t_masked.as_mut(), &masked);
        let on_twin = render(t_twin.as_mut(), &twin);
        let on_unmasked = render(t_unmasked.as_mut(), &unmasked);
        let (e_mask, e_twin) = (rel(&on_masked, &ref_masked), rel(&on_twin, &ref_twin));
        // The method against itself: the masked grille as its twin, the ignored mask not.
        let (d_twin, d_naive) = (rel(&on_masked, &on_twin), rel(&on_unmasked, &on_twin));
        eprintln!(
            "{name}: masked {e_mask:.3} off the reference, twin {e_twin:.3} off its \
             reference; the method's masked picture is {d_twin:.4} off its twin's, with the \
             mask ignored {d_naive:.3}"
        );
        assert!(
            e_mask <= (1.5 * e_twin).max(e_twin + 0.05),
            "{name}: masked {e_mask}, twin {e_twin}"
        );
        assert!(
            d_twin * 4.0 < d_naive,
            "{name}: to the twin {d_twin}, naive {d_naive}"
        );
        checked += 1;
    }
    assert!(checked >= 4, "{checked} methods");
}

/// The grille room lit by nothing but the grille itself: an emissive material under the
/// checkerboard mask (`alpha` the same for every texel when `Some`: 0 masks it all away).
fn lamp_room(grille: Grille, alpha: Option<f32>) -> Scene {
    let mut s = room(grille);
    s.point_lights.clear();
    let m = s.materials.last_mut().unwrap();
    m.emission = Vec3::new(3.0, 2.5, 2.0);
    if let (Some(a), Some(t)) = (alpha, m.albedo_texture) {
        s.textures[t as usize].alpha = Some(vec![a; (CELLS * CELLS) as usize]);
    }
    s.validate().expect("the lamp room is valid");
    s
}

#[test]
fn masked_emitters_emit_from_their_solid_part_in_every_method() {
    // What the reference masks every method masks, emitters included: an emissive grille
    // under the checkerboard lights the room as its twin (the solid squares as geometry)
    // does, not as the whole quad does (about twice the light), and a lamp masked away
    // entirely leaves the room black.
    let (masked, twin, unmasked) = (
        lamp_room(Grille::Masked, None),
        lamp_room(Grille::Twin, None),
        lamp_room(Grille::Unmasked, None),
    );
    let gone = lamp_room(Grille::Masked, Some(0.0));
    let ref_masked = reference(&masked, 5);
    let ref_twin = reference(&twin, 5);
    let noise = rel(&reference(&twin, 6), &ref_twin);
    let e_ref = rel(&ref_masked, &ref_twin);
    eprintln!("reference: masked lamp vs twin {e_ref:.5} (two seeds differ by {noise:.5})");
    assert!(e_ref < 1.5 * noise, "{e_ref} vs noise {noise}");
    assert_eq!(reference(&gone, 5).mean(), Vec3::ZERO, "a lamp masked away");
    let contract = scene_core::contract::check(&gone).unwrap();
    assert!(
        !contract.lit && contract.notes.iter().any(|n| n.contains("no light")),
        "the contract says a lamp masked away gives no light: {contract:?}"
    );
    assert!(scene_core::contract::check(&masked).unwrap().lit);
    let ctx = scene_core::testing::gpu_test_context();
    let methods = || -> Vec<(&str, Box<dyn Technique>)> {
        techniques(ctx.as_ref())
            .into_iter()
            .filter(|(name, _)| *name != "reference")
            .collect()
    };
    let mut checked = 0;
    for ((((name, mut t_masked), (_, mut t_twin)), (_, mut t_unmasked)), (_, mut t_gone)) in
        methods()
            .into_iter()
            .zip(methods())
            .zip(methods())
            .zip(methods())
    {
        let on_masked = render(t_masked.as_mut(), &masked);
        let on_twin = render(t_twin.as_mut(), &twin);
        let on_unmasked = render(t_unmasked.as_mut(), &unmasked);
        let (e_mask, e_twin) = (rel(&on_masked, &ref_masked), rel(&on_twin, &ref_twin));
        let (d_twin, d_naive) = (rel(&on_masked, &on_twin), rel(&on_unmasked, &on_twin));
        let ratio = on_masked.mean().element_sum() / ref_masked.mean().element_sum();
        eprintln!(
            "{name}: masked lamp {e_mask:.3} off the reference (mean {ratio:.3} of it), twin \
             {e_twin:.3} off its reference; the masked picture is {d_twin:.4} off the \
             twin's, with the mask ignored {d_naive:.3}"
        );
        assert!(
            e_mask <= (1.5 * e_twin).max(e_twin + 0.05),
            "{name}: masked lamp {e_mask}, twin {e_twin}"
        );
        assert!(
            d_twin * 4.0 < d_naive,
            "{name}: to the twin {d_twin}, naive {d_naive}"
        );
        let dark = render(t_gone.as_mut(), &gone);
        assert!(
            dark.pixels.iter().all(|p| p.max_element() == 0.0),
            "{name}: a lamp masked away still gives light (mean {})",
            dark.mean()
        );
        checked += 1;
    }
    assert!(checked >= 4, "{checked} methods");
}

#[test]
fn a_scene_masked_away_entirely_is_said_to_be_black() {
    // Every triangle under a mask that nothing reaches: legal, black, and said so.
    let mut s = room(Grille::Masked);
    for m in &mut s.materials {
        m.alpha_cutoff = Some(0.5);
    }
    let contract = scene_core::contract::check(&s).unwrap();
    assert!(
        !contract.notes.iter().any(|n| n.contains("cut away")),
        "the walls have no texture: alpha 1 reaches the cutoff ({contract:?})"
    );
    for m in &mut s.materials {
        m.alpha_cutoff = Some(1.0);
        m.albedo_texture = Some(0);
    }
    s.textures[0].alpha = Some(vec![0.5; (CELLS * CELLS) as usize]);
    for mesh in &mut s.meshes {
        mesh.uvs = Some(vec![Vec2::splat(0.5); mesh.positions.len()]);
    }
    s.validate().unwrap();
    let contract = scene_core::contract::check(&s).unwrap();
    assert!(
        contract
            .notes
            .iter()
            .any(|n| n.contains("every triangle is cut away")),
        "{contract:?}"
    );
}

/// A masked material survives a glTF round trip: `alphaMode: MASK` with its cutoff, the
/// texture's alpha in an RGBA PNG; the re-imported grille casts the same holes.
#[test]
fn masks_round_trip_through_gltf() {
    let masked = room(Grille::Masked);
    let dir = std::env::temp_dir().join(format!("mask-round-trip-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("grille.gltf");
    scene_core::gltf_io::export(&masked, &path).unwrap();
    let back = scene_core::gltf_io::import(&path).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    let m = back
        .scene
        .materials
        .iter()
        .find(|m| m.name == "grille")
        .expect("the grille's material");
    assert_eq!(m.alpha_cutoff, Some(0.5));
    let t = &back.scene.textures[m.albedo_texture.unwrap() as usize];
    let original = masked.textures.last().unwrap();
    assert_eq!(t.alpha, original.alpha);
    let gb = |s: &Scene| {
        let view = View::from_camera(&s.cameras[0]);
        gbuffer::CpuRasterizer::new()
            .render_gbuffer(s, &view, 96, 72)
            .unwrap()
            .depth
    };
    let (a, b) = (gb(&back.scene), gb(&masked));
    let differ: Vec<(usize, f32, f32)> = a
        .iter()
        .zip(&b)
        .enumerate()
        .filter(|(_, (x, y))| (*x - *y).abs() > 1e-5)
        .map(|(i, (x, y))| (i, *x, *y))
        .collect();
    assert!(
        differ.is_empty(),
        "{} pixels differ, first {:?}",
        differ.len(),
        differ.first()
    );
}
