//! Emission textures (glTF's `emissiveTexture`, `scene_core::Material::emission_texture`):
//! a ceiling panel whose emission is a 2 x 2 checkerboard (nearest filter) against its twin,
//! the same panel as four quads of which two emit. The reference resolves the texture per
//! point; the other methods treat each triangle (or relighting's patch) as one emitter of
//! its mean emission, so each must be as close to the reference as on the twin, and its
//! picture of the textured panel much closer to its picture of the twin than with the
//! texture ignored (the whole panel emitting, twice the power).

use golden_tests::scenes::{self, relative_difference as rel, techniques};
use scene_core::glam::{Vec2, Vec3};
use scene_core::scene::{Material, Sampler, Scene, Texture};
use scene_core::{Image, Technique};

const W: u32 = 48;
const H: u32 = 36;
const LO: Vec2 = Vec2::new(0.3, 0.4);
const SIZE: f32 = 0.4;
const EMISSION: f32 = 4.0;

#[derive(Clone, Copy, PartialEq, Debug)]
enum Panel {
    Textured,
    Twin,
    Ignored,
}

fn bright(i: u32, j: u32) -> bool {
    (i + j).is_multiple_of(2)
}

fn room(panel: Panel) -> Scene {
    let mut s = scenes::lit_room(false, false);
    let y = 0.8 - 1e-3;
    let towards = Vec3::new(0.5, 0.0, 0.6);
    let corner = |x: f32, z: f32| Vec3::new(x, y, z);
    let lamp = s.materials.len() as u32;
    let mut m = Material::emissive("lamp", Vec3::splat(0.5), Vec3::splat(EMISSION));
    let mesh = &mut s.meshes[0];
    mesh.uvs = Some(vec![Vec2::ZERO; mesh.positions.len()]);
    match panel {
        Panel::Twin => {
            let dark = lamp + 1;
            let cell = SIZE / 2.0;
            for i in 0..2 {
                for j in 0..2 {
                    let (x, z) = (LO.x + i as f32 * cell, LO.y + j as f32 * cell);
                    mesh.push_quad_facing(
                        [
                            corner(x, z),
                            corner(x + cell, z),
                            corner(x + cell, z + cell),
                            corner(x, z + cell),
                        ],
                        if bright(i, j) { lamp } else { dark },
                        towards,
                    );
                }
            }
        }
        Panel::Textured | Panel::Ignored => {
            let first = mesh.positions.len();
            mesh.push_quad_facing(
                [
                    corner(LO.x, LO.y),
                    corner(LO.x + SIZE, LO.y),
                    corner(LO.x + SIZE, LO.y + SIZE),
                    corner(LO.x, LO.y + SIZE),
                ],
                lamp,
                towards,
            );
            // Texel (i, j) covers x in LO.x + [i, i + 1) SIZE / 2 and z likewise.
            let uvs = mesh.uvs.as_mut().unwrap();
            for (k, p) in mesh.positions.iter().enumerate().skip(first) {
                uvs[k] = (Vec2::new(p.x, p.z) - LO) / SIZE;
            }
            if panel == Panel::Textured {
                s.textures.push(Texture {
                    name: "checker".into(),
                    width: 2,
                    height: 2,
                    texels: (0..4)
                        .map(|k| Vec3::splat(if bright(k % 2, k / 2) { 1.0 } else { 0.0 }))
                        .collect(),
                    alpha: None,
                    sampler: Sampler {
                        nearest: true,
                        ..Default::default()
                    },
                });
                m.emission_texture = Some(s.textures.len() as u32 - 1);
            }
        }
    }
    s.materials.push(m);
    s.materials
        .push(Material::diffuse("dark lamp", Vec3::splat(0.5)));
    s.validate().expect("the panel room is valid");
    s
}

fn render(t: &mut dyn Technique, scene: &Scene) -> Image {
    scenes::render_image(t, scene, W, H)
}

fn reference(scene: &Scene, seed: u64) -> Image {
    scenes::reference_image(scene, 512, seed, W, H)
}

#[test]
fn emission_textures_match_the_reference_in_every_method() {
    let (textured, twin, ignored) = (
        room(Panel::Textured),
        room(Panel::Twin),
        room(Panel::Ignored),
    );
    // The triangles' mean emission: half the panel's factor.
    let e = scene_core::lights::Emitters::new(&textured, &Default::default());
    for t in &e.triangles {
        assert!(
            (t.emission - Vec3::splat(0.5 * EMISSION)).length() < 1e-4,
            "{:?}",
            t.emission
        );
    }
    let ref_tex = reference(&textured, 5);
    let ref_twin = reference(&twin, 5);
    let noise = rel(&reference(&twin, 6), &ref_twin);
    let e_ref = rel(&ref_tex, &ref_twin);
    eprintln!("reference: textured vs twin {e_ref:.4} (two seeds differ by {noise:.4})");
    assert!(e_ref < 1.5 * noise, "{e_ref} vs noise {noise}");
    let ctx = scene_core::testing::gpu_test_context();
    let methods = || {
        techniques(ctx.as_ref())
            .into_iter()
            .filter(|(name, _)| *name != "reference")
            .collect::<Vec<_>>()
    };
    let mut checked = 0;
    for (((name, mut a), (_, mut b)), (_, mut c)) in
        methods().into_iter().zip(methods()).zip(methods())
    {
        let on_tex = render(a.as_mut(), &textured);
        let on_twin = render(b.as_mut(), &twin);
        let on_ignored = render(c.as_mut(), &ignored);
        let (e_tex, e_twin) = (rel(&on_tex, &ref_tex), rel(&on_twin, &ref_twin));
        // The method against itself: the textured panel as its twin, the ignored texture not.
        let (d_twin, d_naive) = (rel(&on_tex, &on_twin), rel(&on_ignored, &on_twin));
        eprintln!(
            "{name}: textured {e_tex:.3} off the reference, twin {e_twin:.3} off its \
             reference; the method's textured picture is {d_twin:.3} off its twin's, with \
             the texture ignored {d_naive:.3}"
        );
        assert!(
            e_tex <= (1.5 * e_twin).max(e_twin + 0.05),
            "{name}: textured {e_tex}, twin {e_twin}"
        );
        // At least twice as close: the IBRR's 8 IRPLs are placed by the emitter table, which
        // differs between the two panels, so its two pictures differ by its noise (0.30).
        assert!(
            d_twin * 2.0 < d_naive,
            "{name}: to the twin {d_twin}, naive {d_naive}"
        );
        checked += 1;
    }
    assert!(checked >= 4, "{checked} methods");
}

/// The emission texture survives a glTF round trip as `emissiveTexture`, and the
/// re-imported panel gives the same mean emission per triangle.
#[test]
fn emission_textures_round_trip_through_gltf() {
    let textured = room(Panel::Textured);
    let dir = std::env::temp_dir().join(format!("emission-round-trip-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("panel.gltf");
    scene_core::gltf_io::export(&textured, &path).unwrap();
    let back = scene_core::gltf_io::import(&path).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert!(back.ignored.is_empty(), "{:?}", back.ignored);
    // The room's own (unused) lamp material comes first; the panel's is the last of the name.
    let lamp = back
        .scene
        .materials
        .iter()
        .rposition(|m| m.name == "lamp")
        .unwrap();
    assert!(back.scene.materials[lamp].emission_texture.is_some());
    let mean = |s: &Scene| -> Vec<Vec3> {
        scene_core::lights::Emitters::new(s, &Default::default())
            .triangles
            .iter()
            .map(|t| t.emission)
            .collect()
    };
    let (a, b) = (mean(&textured), mean(&back.scene));
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert!((*x - *y).length() < 1e-3, "{x} {y}");
    }
}

/// The fuzzer's seed for the material features (`hostile::material_features`) imports with
/// each of them, so its mutations reach their readers.
#[test]
fn the_material_features_seed_imports_with_each_feature() {
    for ext in ["gltf", "glb"] {
        let bytes =
            golden_tests::hostile::exported_scene(&golden_tests::hostile::material_features(), ext);
        let r =
            scene_core::gltf_io::import_slice(&bytes, std::path::Path::new(&format!("seed.{ext}")))
                .unwrap();
        let s = &r.scene;
        assert!(
            s.materials.iter().any(|m| m.alpha_cutoff == Some(0.5)),
            "{ext}: mask"
        );
        assert!(s.textures.iter().any(|t| t.alpha.is_some()), "{ext}: alpha");
        assert!(
            s.materials.iter().any(|m| m.emission_texture.is_some()),
            "{ext}: glow"
        );
        assert!(
            s.meshes.iter().all(|m| m.colors.is_some()),
            "{ext}: colours"
        );
    }
}

/// The reference samples an emission texture by its texels' power
/// (`scene_core::lights::EmissionPattern`): its direct light from the checkerboard panel
/// has the same mean as from the twin (four quads, two of them emitting, sampled by
/// triangle power) and nearly its noise, where sampling each triangle uniformly by area
/// spent half the light samples on dark texels.
#[test]
fn the_reference_samples_emission_textures_by_their_texels() {
    use scene_core::reference::{Bounces, ReferenceSettings, render};
    let settings = ReferenceSettings {
        width: W,
        height: H,
        spp: 256,
        bounces: Bounces::Limited(0),
        seed: 9,
    };
    let out = |scene: &Scene| {
        let cam = scene.cameras[0].with_aspect(W as f32 / H as f32);
        render(scene, &scene_core::View::from_camera(&cam), &settings, None)
    };
    let (tex, twin) = (out(&room(Panel::Textured)), out(&room(Panel::Twin)));
    let sum = |i: &Image| {
        i.pixels
            .iter()
            .map(|p| f64::from(p.x + p.y + p.z))
            .sum::<f64>()
    };
    let (m_tex, m_twin) = (sum(&tex.image), sum(&twin.image));
    // The means' standard error from the per-pixel variances.
    let se = ((sum(&tex.variance) + sum(&twin.variance)) / f64::from(settings.spp)).sqrt();
    let ratio = sum(&tex.variance) / sum(&twin.variance);
    eprintln!(
        "direct light: textured {m_tex:.3}, twin {m_twin:.3} (SE {se:.3}); variance ratio {ratio:.3}"
    );
    assert!(
        (m_tex - m_twin).abs() < 4.0 * se,
        "{m_tex} vs {m_twin}, SE {se}"
    );
    assert!(ratio < 1.3, "textured panel's variance {ratio}x the twin's");
}
