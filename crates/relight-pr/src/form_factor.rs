//! Form factors from a receiving point to a shooting patch, the quantity progressive
//! refinement distributes energy with (`Delta B_j = rho_j B_unshot,i F_ji`, the paper's
//! figure 2).
//!
//! The ray-cast method: the unoccluded point-to-polygon form factor in closed form
//! (Lambert's formula, the patch first clipped to the receiver's upper hemisphere), times
//! the fraction of `samples` stratified points on the patch that the receiver sees through
//! scene-core's BVH. The closed form stays exact as the distance goes to zero (touching and
//! coincident elements), where point-sampled `cos cos / (pi r^2)` diverges.

use glam::{Vec2, Vec3};
use scene_core::sampling::{hash_seed, r2, uniform_triangle};

/// The unoccluded form factor from a differential area at `x` with unit normal `n` to the
/// polygon `poly` (planar, convex, either winding): Lambert's formula
/// `F = 1/(2 pi) sum_i theta_i n . unit(R_i x R_i+1)` over the part of the polygon above
/// the tangent plane of `x`.
pub fn point_to_polygon(x: Vec3, n: Vec3, poly: &[Vec3]) -> f32 {
    let (clipped, count) = clip_above(x, n, poly);
    if count < 3 {
        return 0.0;
    }
    let mut sum = 0.0f32;
    for i in 0..count {
        let a = (clipped[i] - x).normalize_or_zero();
        let b = (clipped[(i + 1) % count] - x).normalize_or_zero();
        let c = a.cross(b);
        let len = c.length();
        if len <= 0.0 {
            continue;
        }
        let theta = len.atan2(a.dot(b));
        sum += theta * n.dot(c / len);
    }
    (sum.abs() / (2.0 * std::f32::consts::PI)).clamp(0.0, 1.0)
}

/// The part of the convex polygon `poly` on or above the plane through `x` with normal
/// `n` (Sutherland and Hodgman against one plane): up to 8 corners, and how many.
pub(crate) fn clip_above(x: Vec3, n: Vec3, poly: &[Vec3]) -> ([Vec3; 8], usize) {
    let mut clipped: [Vec3; 8] = [Vec3::ZERO; 8];
    let mut count = 0;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let (da, db) = (n.dot(a - x), n.dot(b - x));
        if da >= 0.0 && count < 8 {
            clipped[count] = a;
            count += 1;
        }
        if (da >= 0.0) != (db >= 0.0) && count < 8 {
            let t = da / (da - db);
            clipped[count] = a + (b - a) * t;
            count += 1;
        }
    }
    (clipped, count)
}

/// A point drawn uniformly (by `u`, and `pick` in `[0, 1)` for the piece) on the part of
/// triangle `corners` above the plane through `x` with normal `n` ([`clip_above`]): the
/// part a point-to-triangle form factor counts, where a visibility ray from `x` is to go.
/// `None` where no part of it is (or the part has no area).
pub(crate) fn point_above(
    corners: &[Vec3; 3],
    x: Vec3,
    n: Vec3,
    u: Vec2,
    pick: f32,
) -> Option<Vec3> {
    let (poly, count) = clip_above(x, n, corners);
    if count < 3 {
        return None;
    }
    // A fan from the first corner: the piece is picked by area.
    let area = |i: usize| 0.5 * (poly[i] - poly[0]).cross(poly[i + 1] - poly[0]).length();
    let total: f32 = (1..count - 1).map(area).sum();
    if total.is_nan() || total <= 0.0 || !total.is_finite() {
        return None;
    }
    let mut left = pick * total;
    let mut piece = count - 2;
    for i in 1..count - 1 {
        left -= area(i);
        if left < 0.0 {
            piece = i;
            break;
        }
    }
    Some(crate::mesh::uniform_point_on(
        &[poly[0], poly[piece], poly[piece + 1]],
        u,
    ))
}

/// The form factor from a receiver at `x` (unit normal `n`) to the one-sided triangle
/// `tri` (unit normal `tri_n` of its emitting side): zero when `x` is behind the triangle,
/// else [`point_to_polygon`] times the fraction of `samples` stratified points of the
/// triangle visible from `x` through `rays` (no rays when `rays` is `None`). `seed` fixes
/// the sample pattern of this receiver-patch pair, so the value does not depend on the
/// order in which patches shoot.
pub fn point_to_triangle<O: crate::visibility::Occlusion + ?Sized>(
    x: Vec3,
    n: Vec3,
    tri: &[Vec3; 3],
    tri_n: Vec3,
    rays: Option<&O>,
    samples: u32,
    seed: u64,
) -> f32 {
    point_to_triangle_with(x, n, tri, tri_n, rays, |_| samples, seed)
}

/// [`point_to_triangle`] with as many visibility rays as the receiver's share of the
/// patch's light asks: `max_samples` when the unoccluded form factor is `full_at` or more,
/// in proportion below it, at least one. Every ray count gives an unbiased estimate of the
/// visible fraction; the rays go where a wrong fraction would show (a receiver near the
/// patch, its contact shadows), not to the far receivers that each get a sliver of its
/// light (in a building, the thousands of elements of other rooms that face the shooter
/// behind walls).
pub fn point_to_triangle_adaptive<O: crate::visibility::Occlusion + ?Sized>(
    x: Vec3,
    n: Vec3,
    tri: &[Vec3; 3],
    tri_n: Vec3,
    rays: &O,
    (max_samples, full_at): (u32, f32),
    seed: u64,
) -> f32 {
    let samples = |f: f32| adaptive_samples(f, max_samples, full_at);
    point_to_triangle_with(x, n, tri, tri_n, Some(rays), samples, seed)
}

/// The visibility rays for an unoccluded form factor `f`: `max_samples * f / full_at`
/// rounded up, between 1 and `max_samples` (all of them when `full_at` is not positive).
pub fn adaptive_samples(f: f32, max_samples: u32, full_at: f32) -> u32 {
    if full_at > 0.0 && f < full_at {
        ((max_samples as f32 * f / full_at).ceil() as u32).clamp(1, max_samples.max(1))
    } else {
        max_samples
    }
}

fn point_to_triangle_with<O: crate::visibility::Occlusion + ?Sized>(
    x: Vec3,
    n: Vec3,
    tri: &[Vec3; 3],
    tri_n: Vec3,
    rays: Option<&O>,
    samples: impl FnOnce(f32) -> u32,
    seed: u64,
) -> f32 {
    let centre = (tri[0] + tri[1] + tri[2]) / 3.0;
    // In front of the patch by more than rounding: a receiver in the patch's plane and
    // facing along it (on the same wall) sees it edge-on, whatever the last bits of a
    // scaled position say.
    let size = (tri[1] - tri[0]).length().max((tri[2] - tri[0]).length());
    // A receiver at a right angle to the patch (the floor at the foot of a wall) keeps its
    // form factor however close it is: its hemisphere holds the patch whole.
    let height = tri_n.dot(x - centre);
    if height <= 0.0 || (height <= 1e-5 * size && n.dot(tri_n).abs() > 0.5) {
        return 0.0;
    }
    let f = point_to_polygon(x, n, tri);
    if f <= 0.0 {
        return 0.0;
    }
    let Some(rays) = rays else {
        return f;
    };
    let samples = samples(f).max(1);
    let offset = r2(hash_seed(seed, 0x5eed, 0), glam::Vec2::ZERO);
    let mut visible = 0u32;
    let mut tried = 0u32;
    for s in 0..samples {
        let b = uniform_triangle(r2(s as u64, offset));
        let q = tri[0] * (1.0 - b.x - b.y) + tri[1] * b.x + tri[2] * b.y;
        let d = q - x;
        let dist = d.length();
        if dist.is_nan() || dist <= 0.0 {
            continue;
        }
        let dir = d / dist;
        // Only points above the receiver's tangent plane carry form factor.
        if n.dot(dir) <= 0.0 {
            continue;
        }
        tried += 1;
        if crate::visibility::sees_surface_point(rays, x, n, q, dist) {
            visible += 1;
        }
    }
    if tried == 0 {
        // Every sample below the horizon: the clipped sliver gets the unoccluded value.
        return f;
    }
    f * visible as f32 / tried as f32
}

/// The hemicube's delta form factors of a face rendered from `view` at `width x height`
/// (the paper's method, after Cohen and Greenberg): a pixel whose centre is seen along
/// direction `p` (scaled to unit distance along the face's axis) covers the face-plane area
/// `dA` and has `dF = max(p . n, 0) dA / (pi |p|^4)`, `n` the hemicube's normal: the top
/// face's `dA / (pi (1 + x^2 + y^2)^2)` and the side faces' `z dA / (pi (1 + x^2 + z^2)^2)`
/// in one formula. Over the five faces they sum to 1.
pub fn delta_form_factors(
    view: &scene_core::View,
    normal: Vec3,
    width: u32,
    height: u32,
) -> Vec<f32> {
    let scene_core::Projection::Perspective {
        left,
        right,
        bottom,
        top,
    } = view.projection
    else {
        return vec![0.0; width as usize * height as usize];
    };
    let da = (right - left) * (top - bottom) / (width as f32 * height as f32);
    let f = view.forward;
    (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| {
            let uv = glam::Vec2::new(
                (x as f32 + 0.5) / width as f32,
                (y as f32 + 0.5) / height as f32,
            );
            let (_, d) = view.ray(uv);
            let along = d.dot(f);
            if along <= 0.0 {
                return 0.0;
            }
            let p = d / along;
            let r2 = p.length_squared();
            (p.dot(normal).max(0.0) * da / (std::f32::consts::PI * r2 * r2)).max(0.0)
        })
        .collect()
}

/// One row of form factors by the hemicube: `F[j]`, the form factor from a differential
/// area at `point` with unit `normal` to element `j`, from the five faces of a hemicube of
/// `resolution` rendered by `renderer` (prepared with the element scene, so triangle ids
/// are element ids) and their delta form factors. Visibility is the renderer's depth test.
/// `receiver_normals[j]` is element `j`'s unit normal: a pixel that sees an element from
/// behind gives it nothing (elements are one-sided, and G-buffer normals are flipped to
/// face the viewer, so the element's own normal decides). Without this rule a thin wall
/// leaks: the back of the neighbouring room's wall, seen through the rasteriser's or ray
/// caster's cracks, would receive.
#[allow(clippy::too_many_arguments)]
pub fn hemicube_row(
    renderer: &mut dyn scene_core::GBufferRenderer,
    point: Vec3,
    normal: Vec3,
    resolution: u32,
    near: f32,
    far: f32,
    receiver_normals: &[Vec3],
) -> Result<Vec<f32>, scene_core::Error> {
    let elements = receiver_normals.len();
    let faces = renderer.render_hemicube(point, normal, resolution, near, far)?;
    let mut row = vec![0.0f32; elements];
    for face in &faces {
        let g = &face.gbuffer;
        let delta = delta_form_factors(&face.view, normal, g.width, g.height);
        for (i, df) in delta.iter().enumerate() {
            let id = g.triangle_id[i] as usize;
            if g.is_background(i) || id >= elements {
                continue;
            }
            let uv = scene_core::view::pixel_uv(
                i as u32 % g.width,
                i as u32 / g.width,
                g.width,
                g.height,
            );
            let (_, dir) = face.view.ray(uv);
            if receiver_normals[id].dot(dir) < 0.0 {
                row[id] += df;
            }
        }
    }
    Ok(row)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The points lie on the triangle's part in front of the plane, spread uniformly over
    /// it: their mean is that part's centroid (here the triangle (0,0), (2,0), (0,2) cut at
    /// x = 1, whose front part is the triangle (1,0), (2,0), (1,1), centroid (4/3, 1/3)).
    #[test]
    fn points_above_a_plane_cover_the_part_in_front_uniformly() {
        let tri = [
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        ];
        let (x, n) = (Vec3::new(1.0, 5.0, 0.0), Vec3::X);
        let mut rng = scene_core::sampling::Rng::new(7, 1);
        let count = 20_000;
        let mut mean = Vec3::ZERO;
        for _ in 0..count {
            let q = point_above(&tri, x, n, rng.next_vec2(), rng.next_f32()).unwrap();
            assert!(
                q.x >= 1.0 - 1e-5 && q.x + q.y <= 2.0 + 1e-5 && q.y >= -1e-6,
                "{q}"
            );
            mean += q / count as f32;
        }
        let expect = Vec3::new(4.0 / 3.0, 1.0 / 3.0, 0.0);
        assert!(mean.distance(expect) < 0.01, "{mean} against {expect}");
        // Facing the other way, the part in front is the quadrilateral left of x = 1; a
        // triangle wholly behind the plane has none.
        let q = point_above(&tri, x, -n, Vec2::new(0.3, 0.6), 0.7).unwrap();
        assert!(q.x <= 1.0 + 1e-5, "{q}");
        assert!(point_above(&tri, Vec3::new(3.0, 0.0, 0.0), n, Vec2::splat(0.5), 0.5).is_none());
    }

    #[test]
    fn a_large_parallel_polygon_overhead_approaches_one() {
        let s = 1e4;
        let quad = [
            Vec3::new(-s, 1.0, -s),
            Vec3::new(s, 1.0, -s),
            Vec3::new(s, 1.0, s),
            Vec3::new(-s, 1.0, s),
        ];
        let f = point_to_polygon(Vec3::ZERO, Vec3::Y, &quad);
        assert!((f - 1.0).abs() < 1e-3, "{f}");
        // Behind the receiver: nothing.
        assert_eq!(point_to_polygon(Vec3::ZERO, -Vec3::Y, &quad), 0.0);
        // Half of it below the tangent plane of a tilted receiver: half.
        let f = point_to_polygon(Vec3::ZERO, Vec3::X, &quad);
        assert!((f - 0.5).abs() < 1e-3, "{f}");
    }

    #[test]
    fn a_small_patch_matches_the_point_estimate() {
        // A 1 cm square 1 m overhead: cos cos A / (pi r^2).
        let h = 0.005;
        let quad = [
            Vec3::new(-h, 1.0, -h),
            Vec3::new(h, 1.0, -h),
            Vec3::new(h, 1.0, h),
            Vec3::new(-h, 1.0, h),
        ];
        let f = point_to_polygon(Vec3::ZERO, Vec3::Y, &quad);
        let expect = 1e-4 / std::f32::consts::PI;
        assert!((f - expect).abs() < 1e-3 * expect, "{f} vs {expect}");
    }
}
