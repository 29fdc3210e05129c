//! The default view of a scene that has no camera ([`framing_camera`]): of a few
//! candidate views around and inside the scene's bounds, the one that sees the most lit
//! surface.
//!
//! Outside views look at the bounding sphere's centre from four sides, a little above,
//! filling a 50 degree field of view; inside views stand at the centre and look along the
//! four horizontal axes with a 70 degree field of view. Each candidate casts a 16 x 12 grid
//! of rays; a hit counts when a light sees it (a shadow ray to each point light, against
//! each directional light, to the centroid of up to 8 emissive triangles). An interior (a
//! closed room lit from inside) is framed from inside, an object from outside, a room open
//! on one side through its opening. Ties keep the earlier candidate (outside first), so the
//! choice is deterministic.

use glam::Vec3;

use crate::lights::Emitters;
use crate::ray::RayScene;
use crate::scene::{Camera, Scene};
use crate::view::{View, pixel_uv};

/// The candidate views of `scene`, outside ones first.
fn candidates(scene: &Scene) -> Vec<Camera> {
    let b = scene.bounds();
    let diagonal = b.diagonal();
    let (centre, radius) = if b.is_empty() || diagonal.is_nan() || diagonal <= 0.0 {
        (Vec3::ZERO, 0.5 * 3f32.sqrt())
    } else {
        (b.center(), 0.5 * diagonal)
    };
    let outside_fov = 50f32.to_radians();
    let distance = radius / (0.5 * outside_fov).sin();
    let mut out = Vec::new();
    for (i, d) in [
        Vec3::new(0.35, 0.45, 1.0),
        Vec3::new(-0.35, 0.45, -1.0),
        Vec3::new(1.0, 0.45, -0.35),
        Vec3::new(-1.0, 0.45, 0.35),
    ]
    .into_iter()
    .enumerate()
    {
        out.push(Camera {
            name: format!("framing (outside {i})"),
            position: centre + d.normalize() * distance,
            target: centre,
            up: Vec3::Y,
            fov_y: outside_fov,
            aspect: 4.0 / 3.0,
            near: radius * 1e-3,
            far: distance + 2.0 * radius,
        });
    }
    for (i, d) in [Vec3::Z, -Vec3::Z, Vec3::X, -Vec3::X]
        .into_iter()
        .enumerate()
    {
        out.push(Camera {
            name: format!("framing (inside {i})"),
            position: centre,
            target: centre + d * radius,
            up: Vec3::Y,
            fov_y: 70f32.to_radians(),
            aspect: 4.0 / 3.0,
            near: radius * 1e-3,
            far: 2.0 * radius,
        });
    }
    out
}

/// How many of a 16 x 12 grid of each candidate's rays hit a lit surface.
fn scores(scene: &Scene, cands: &[Camera]) -> Vec<usize> {
    let rays = RayScene::build(scene);
    let eps = scene.extent() * 1e-5;
    let emitters = Emitters::new(scene, &crate::LightState::default());
    let step = (emitters.triangles.len() / 8).max(1);
    let emitter_points: Vec<Vec3> = emitters
        .triangles
        .iter()
        .step_by(step)
        .take(8)
        .map(|t| (t.corners[0] + t.corners[1] + t.corners[2]) / 3.0 + t.normal * eps)
        .collect();
    let far = scene.extent() * 4.0;
    let lit = |p: Vec3| {
        scene.point_lights.iter().any(|l| {
            let d = l.position - p;
            let dist = d.length();
            dist > 0.0
                && l.attenuation(-d / dist) > 0.0
                && !rays.occluded(p, d / dist, 0.0, dist * (1.0 - 1e-4))
        }) || crate::lights::directional_sources(scene)
            .iter()
            .any(|(_, l)| {
                let d = -l.direction.normalize_or_zero();
                d != Vec3::ZERO && !rays.occluded(p, d, 0.0, far)
            })
            || emitter_points.iter().any(|&e| {
                let d = e - p;
                let dist = d.length();
                dist > 0.0 && !rays.occluded(p, d / dist, 0.0, dist * (1.0 - 1e-4))
            })
    };
    let (w, h) = (16u32, 12u32);
    cands
        .iter()
        .map(|cam| {
            let view = View::from_camera(cam);
            let mut score = 0;
            for y in 0..h {
                for x in 0..w {
                    let (o, d) = view.ray(pixel_uv(x, y, w, h));
                    if let Some(hit) = rays.closest_hit(o, d, cam.near, f32::INFINITY) {
                        // Step back towards the eye, off the surface.
                        let p = o + d * (hit.t - eps.max(hit.t * 1e-5));
                        if lit(p) {
                            score += 1;
                        }
                    }
                }
            }
            score
        })
        .collect()
}

/// The default view of `scene` (see the module documentation): what every command that
/// takes a scene file uses as camera 0 when the file has none.
pub fn framing_camera(scene: &Scene) -> Camera {
    let cands = candidates(scene);
    if scene.triangle_count() == 0 {
        return cands[0].clone();
    }
    let s = scores(scene, &cands);
    let mut best = 0;
    for (k, &v) in s.iter().enumerate() {
        if v > s[best] {
            best = k;
        }
    }
    cands[best].clone()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin;

    #[test]
    fn the_view_that_sees_the_most_lit_surface_is_chosen() {
        let cornell = builtin::scene("cornell").unwrap();
        let cands = candidates(&cornell);
        let s = scores(&cornell, &cands);
        // Behind the closed back wall (+z) nothing lit is seen; through the opening (-z)
        // and from inside, much is.
        assert_eq!(s[0], 0, "{s:?}");
        assert!(s[1] > 0, "{s:?}");
        let cam = framing_camera(&cornell);
        let chosen = cands.iter().position(|c| c.name == cam.name).unwrap();
        assert_eq!(s[chosen], *s.iter().max().unwrap());
        assert!(s[chosen] > 16 * 12 / 2, "{s:?}");
        // A closed room lit from inside: only an inside view sees light.
        let mut room = Scene::new("room");
        room.materials
            .push(crate::Material::diffuse("white", Vec3::splat(0.7)));
        let mut m = crate::Mesh {
            name: "room".into(),
            ..Default::default()
        };
        m.push_box(Vec3::ZERO, Vec3::new(2.0, 1.0, 1.5), 0.0, 0);
        room.meshes.push(m);
        room.point_lights.push(crate::PointLight {
            name: "lamp".into(),
            position: Vec3::new(0.3, 0.5, 0.2),
            intensity: Vec3::ONE,
            radius: None,
            cone: None,
        });
        let cam = framing_camera(&room);
        assert!(cam.name.contains("inside"), "{}", cam.name);
        // Every candidate passes the camera check.
        for (i, c) in candidates(&room).iter().enumerate() {
            c.check(i).unwrap();
        }
        // No geometry: the first outside view.
        assert!(
            framing_camera(&Scene::new("empty"))
                .name
                .contains("outside 0")
        );
    }
}
