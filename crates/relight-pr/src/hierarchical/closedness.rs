//! The normalisation's rays: how much of each unit of surface's cosine-weighted
//! hemisphere other reflecting surfaces cover ([`closedness`]), against which the
//! hierarchical solve scales the sums of its links' form factors.

use glam::Vec3;
use rayon::prelude::*;
use scene_core::ray::RayScene;
use scene_core::sampling::{Rng, hash_seed};
use scene_core::{Scene, luminance};

use crate::mesh::{ElementGroups, Meshing};

/// Rays per element of [`closedness`]; [`CLOSED_RAYS_OPEN`] in all where any misses.
const CLOSED_RAYS: u32 = 32;

/// Rays per element of [`closedness`] where the first [`CLOSED_RAYS`] did not all meet a
/// surface (a window's share of the hemisphere has 4x less noise).
const CLOSED_RAYS_OPEN: u32 = 128;

/// Rays per group of [`closedness`] where the element budget grouped the mesh elements
/// (the normalisation then only uses a group's total); [`CLOSED_GROUP_RAYS_OPEN`] in all
/// where any misses.
pub(super) const CLOSED_GROUP_RAYS: u32 = 64;

/// Rays per group of [`closedness`] where the first [`CLOSED_GROUP_RAYS`] did not all meet
/// a surface: the binomial noise of a group open to the sky on a tenth of its hemisphere
/// is then under 1 %.
const CLOSED_GROUP_RAYS_OPEN: u32 = 1024;

/// Per unit of surface (a mesh element, or where `groups` is given, a group's mesh
/// elements that `eligible` marks), the share of its cosine-weighted hemisphere in which a
/// ray meets the front of a surface that reflects (stratified rays from points spread over
/// it by area), times its area where grouped: the sum of its exact form factors to the
/// surfaces its links can reach. Black surfaces count as open (the refinement drops
/// senders that send nothing); a ray whose first hit is a back face started inside a
/// solid and is not counted. `None` where no ray met a surface that reflects: the links'
/// sum is then kept.
pub(super) fn closedness(
    scene: &Scene,
    meshing: &Meshing,
    rays: &RayScene,
    extent: f32,
    groups: Option<(&ElementGroups, &[bool])>,
) -> Vec<Option<f64>> {
    let offsets = scene.mesh_offsets();
    // Which side of the triangle a ray along `d` meets.
    enum Side {
        Reflects,
        Black,
        Back,
    }
    let side = |triangle: u32, d: Vec3| {
        let m = offsets
            .partition_point(|&o| o <= triangle)
            .saturating_sub(1);
        let mesh = &scene.meshes[m];
        let local = (triangle - offsets[m]) as usize;
        let t = mesh.indices[local];
        let p = t.map(|i| mesh.positions[i as usize]);
        let mut g = (p[1] - p[0]).cross(p[2] - p[0]);
        if !mesh.normals.is_empty() {
            let shading: Vec3 = t.iter().map(|&i| mesh.normals[i as usize]).sum();
            if g.dot(shading) < 0.0 {
                g = -g;
            }
        }
        let material = &scene.materials[mesh.material_ids[local] as usize];
        if g.dot(d) >= 0.0 {
            Side::Back
        } else if luminance(material.albedo) > 0.0 {
            Side::Reflects
        } else {
            Side::Black
        }
    };
    let els = &meshing.elements;
    // The share over a unit's elements (`members`, cumulative areas `cumulative`): rays in
    // two rounds, the second only where the first did not all meet a reflecting surface.
    let share = |unit: u64, members: &[u32], cumulative: &[f32], rounds: [u32; 2]| {
        let total = *cumulative.last()?;
        let mut rng = Rng::new(hash_seed(0xc105ed, unit, 0), 0x29);
        let offset = rng.next_vec2();
        // Rays that first meet a back face start inside a solid (a point of the shelf
        // under a book): they are not counted.
        let (mut hits, mut valid, mut cast) = (0u32, 0u32, 0u32);
        for round in rounds {
            if cast == round || (cast > 0 && hits == valid) {
                break;
            }
            for i in cast..round {
                let e = if members.len() == 1 {
                    &els[members[0] as usize]
                } else {
                    let pick = rng.next_f32() * total;
                    let at = cumulative.partition_point(|&c| c <= pick);
                    &els[members[at.min(members.len() - 1)] as usize]
                };
                let x = e.uniform_point(rng.next_vec2());
                let d = scene_core::sampling::cosine_hemisphere(
                    e.normal,
                    scene_core::sampling::r2(i as u64, offset),
                );
                let hit = rays.closest_hit(x + e.normal * (1e-5 * extent), d, 0.0, f32::MAX);
                match hit.map(|h| side(h.triangle, d)) {
                    Some(Side::Back) => {}
                    Some(Side::Reflects) => {
                        hits += 1;
                        valid += 1;
                    }
                    _ => valid += 1,
                }
            }
            cast = round;
        }
        (hits > 0).then(|| hits as f64 / valid as f64)
    };
    let Some((groups, eligible)) = groups else {
        return els
            .par_iter()
            .enumerate()
            .map(|(j, e)| {
                if e.hidden {
                    return Some(0.0);
                }
                share(
                    j as u64,
                    &[j as u32],
                    &[e.area],
                    [CLOSED_RAYS, CLOSED_RAYS_OPEN],
                )
            })
            .collect();
    };
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); groups.count];
    for (j, e) in els.iter().enumerate() {
        if eligible[j] && !e.hidden && e.area > 0.0 {
            members[groups.of(j)].push(j as u32);
        }
    }
    members
        .par_iter()
        .enumerate()
        .map(|(g, m)| {
            let cumulative: Vec<f32> = m
                .iter()
                .scan(0.0f32, |a, &j| {
                    *a += els[j as usize].area;
                    Some(*a)
                })
                .collect();
            let rounds = [CLOSED_GROUP_RAYS, CLOSED_GROUP_RAYS_OPEN];
            share(g as u64, m, &cumulative, rounds).map(|c| c * *cumulative.last().unwrap() as f64)
        })
        .collect()
}
