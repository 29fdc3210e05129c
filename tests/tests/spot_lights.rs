//! Spot lights (glTF's `spot`: a point light with a cone, `scene_core::lights::SpotCone`)
//! in every method against the reference path tracer: a room lit by a spot pointing at its
//! floor. Each method must be as close to the reference's spot picture as it is, on the same
//! room, to the reference's picture of a plain point light (its usual error), and much
//! closer than its own picture of the point light that the spot would have been without its
//! cone (what importing spots as points gave).

use golden_tests::scenes::{self, relative_difference as rel};
use scene_core::glam::Vec3;
use scene_core::lights::SpotCone;
use scene_core::scene::{PointLight, Scene};
use scene_core::{Image, Technique};

const W: u32 = 48;
const H: u32 = 36;

/// The lit room with its bulb replaced by `light`.
fn room_with(light: PointLight) -> Scene {
    let mut s = scenes::lit_room(false, false);
    s.point_lights.push(light);
    s.validate().expect("the room is valid");
    s
}

/// A spot under the ceiling pointing at the floor, and the same light without its cone.
fn spot_and_point() -> (Scene, Scene) {
    let spot = PointLight {
        cone: Some(SpotCone {
            direction: Vec3::new(0.0, -1.0, -0.2),
            inner: 0.25,
            outer: 0.5,
        }),
        ..PointLight::new("spot", Vec3::new(0.5, 0.75, 0.55), Vec3::splat(1.5))
    };
    let point = PointLight {
        cone: None,
        ..spot.clone()
    };
    (room_with(spot), room_with(point))
}

fn reference(scene: &Scene) -> Image {
    reference_seeded(scene, 5)
}

fn reference_seeded(scene: &Scene, seed: u64) -> Image {
    scenes::reference_image(scene, 512, seed, W, H)
}

fn methods() -> Vec<(&'static str, Box<dyn Technique>)> {
    scenes::compared_methods()
}

fn render(t: &mut dyn Technique, scene: &Scene) -> Image {
    scenes::render_image(t, scene, W, H)
}

#[test]
fn spot_lights_match_the_reference_in_every_method() {
    let (spot, point) = spot_and_point();
    let ref_spot = reference(&spot);
    let ref_point = reference(&point);
    // The cone matters: the spot's picture is far from the point light's.
    let cone_effect = rel(&ref_point, &ref_spot);
    eprintln!("reference: the point light's picture differs from the spot's by {cone_effect:.3}");
    assert!(cone_effect > 0.5, "{cone_effect}");
    let pairs = methods().into_iter().zip(methods());
    let mut checked = 0;
    for ((name, mut on_spot), (_, mut on_point)) in pairs {
        let e_spot = rel(&render(on_spot.as_mut(), &spot), &ref_spot);
        let point_image = render(on_point.as_mut(), &point);
        let e_usual = rel(&point_image, &ref_point);
        let e_naive = rel(&point_image, &ref_spot);
        eprintln!(
            "{name}: spot {e_spot:.3} off the reference, point light {e_usual:.3} off its \
             reference; the point light's picture is {e_naive:.3} off the spot's"
        );
        assert!(
            e_spot <= (1.5 * e_usual).max(e_usual + 0.05),
            "{name}: spot {e_spot}, usual {e_usual}"
        );
        assert!(
            e_spot * 2.0 < e_naive,
            "{name}: spot {e_spot}, naive {e_naive}"
        );
        checked += 1;
    }
    assert!(checked >= 4, "{checked} methods");
}

/// A spot survives a glTF round trip (exported as `KHR_lights_punctual` `spot`, imported
/// with its cone about the node's -Z) and renders the same in the reference, within its
/// noise.
#[test]
fn spot_lights_round_trip_through_gltf() {
    let (spot, _) = spot_and_point();
    let dir = std::env::temp_dir().join(format!("spot-round-trip-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("spot.gltf");
    scene_core::gltf_io::export(&spot, &path).unwrap();
    let back = scene_core::gltf_io::import(&path).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    let (a, b) = (&spot.point_lights[0], &back.scene.point_lights[0]);
    let (ca, cb) = (a.cone.unwrap(), b.cone.expect("the cone came back"));
    assert!((ca.axis() - cb.axis()).length() < 1e-5, "{ca:?} {cb:?}");
    assert_eq!((ca.inner, ca.outer), (cb.inner, cb.outer));
    // The same picture within the reference's noise (the file orders triangles its own
    // way, so the same seed traces other paths): measured as two seeds' difference.
    let noise = rel(&reference_seeded(&spot, 6), &reference(&spot));
    let e = rel(&reference(&back.scene), &reference(&spot));
    eprintln!("round trip: {e:.4} (two seeds differ by {noise:.4})");
    assert!(e < 1.5 * noise, "{e} vs noise {noise}");
}
