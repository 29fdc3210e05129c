//! The cluster tree of the hierarchical solve: nodes over the elements, grouped by
//! orientation then in space, their coherence, and how one node's leaves face another.

use glam::Vec3;
use rayon::prelude::*;
use scene_core::ray::RayScene;
use scene_core::sampling::{Rng, hash_seed};

use crate::mesh::Meshing;
use crate::visibility;

pub(super) const NONE: u32 = u32::MAX;

/// A node of the cluster tree. Nodes are in pre-order (a parent before its children).
#[derive(Clone, Copy, Debug)]
pub(super) struct Node {
    /// Its leaves: `order[first..first + count]` (element ids).
    pub(super) first: u32,
    pub(super) count: u32,
    /// Children, or [`NONE`] for a leaf.
    pub(super) children: [u32; 2],
    /// Area-weighted centroid of its leaves.
    pub(super) centre: Vec3,
    /// Radius of a sphere about `centre` holding its leaves.
    pub(super) radius: f32,
    pub(super) lo: Vec3,
    pub(super) hi: Vec3,
    /// Mean normal (area-weighted, unit; zero where they cancel).
    pub(super) normal: Vec3,
    /// Half-angle of a cone about `normal` holding every leaf's normal (pi when none does).
    pub(super) cone: f32,
    /// The cone's sine and cosine.
    pub(super) cone_sin_cos: [f32; 2],
    /// Smallest and largest `normal . x` over its leaves' corners (for flat nodes).
    pub(super) plane: [f32; 2],
    pub(super) area: f32,
}

impl Node {
    pub(super) fn leaf(&self) -> bool {
        self.children[0] == NONE
    }
    /// Every leaf's normal is `normal` (to rounding).
    pub(super) fn flat(&self) -> bool {
        self.cone < 1e-4
    }

    /// Every leaf's normal within [`NEARLY_FLAT`] of `normal`: a floor, a wall, a table
    /// top and the face of a box against it, which the element budget's coherence rules
    /// treat as one surface (a cone of rounding, 1e-4, let a slab's face and the wall it
    /// stands against pass as furniture, and their cluster shared out the dark of the
    /// pressed part: 15 % dark in the touching-clusters furnace).
    pub(super) fn nearly_flat(&self) -> bool {
        self.cone < NEARLY_FLAT
    }
}

/// The cluster tree over the elements that are not hidden.
pub(super) struct Tree {
    pub(super) nodes: Vec<Node>,
    /// Element ids in leaf order.
    pub(super) order: Vec<u32>,
    /// Prefix sums of leaf area in `order` (`len + 1` entries).
    pub(super) area_prefix: Vec<f64>,
    /// The leaf node of each element ([`NONE`] for hidden ones).
    pub(super) leaf_of: Vec<u32>,
    /// Whether the node's leaves see each other ([`Tree::coherence`]): only such nodes
    /// end far links.
    pub(super) coherent: Vec<bool>,
}

/// The orientation class of a normal: its cube-map face and a 3 x 3 cell on it (axis
/// directions at cell centres).
pub(super) fn orientation_class(n: Vec3) -> u32 {
    let a = n.abs();
    let (face, u, v, d) = if a.x >= a.y && a.x >= a.z {
        (if n.x > 0.0 { 0 } else { 1 }, n.y, n.z, a.x)
    } else if a.y >= a.z {
        (if n.y > 0.0 { 2 } else { 3 }, n.x, n.z, a.y)
    } else {
        (if n.z > 0.0 { 4 } else { 5 }, n.x, n.y, a.z)
    };
    let cell = |t: f32| (((t / d.max(1e-12) + 1.0) * 1.5) as u32).min(2);
    face * 9 + cell(u) * 3 + cell(v)
}

impl Tree {
    /// The tree over `meshing`'s elements, with its clusters' coherence found through
    /// `rays`.
    pub(super) fn build(meshing: &Meshing, rays: &RayScene) -> Self {
        let els = &meshing.elements;
        let mut keyed: Vec<(u32, u32)> = (0..els.len() as u32)
            .filter(|&j| {
                let e = &els[j as usize];
                !e.hidden && e.area > 0.0 && e.area.is_finite()
            })
            .map(|j| (orientation_class(els[j as usize].normal), j))
            .collect();
        keyed.sort_unstable();
        let class: Vec<u32> = keyed.iter().map(|k| k.0).collect();
        let mut order: Vec<u32> = keyed.iter().map(|k| k.1).collect();
        let mut nodes = Vec::with_capacity(2 * order.len());
        if !order.is_empty() {
            let count = order.len();
            build_node(els, &class, &mut order, 0, count, &mut nodes);
        }
        let mut area_prefix = Vec::with_capacity(order.len() + 1);
        let mut sum = 0.0f64;
        area_prefix.push(0.0);
        for &j in &order {
            sum += els[j as usize].area as f64;
            area_prefix.push(sum);
        }
        let mut leaf_of = vec![NONE; els.len()];
        for (i, node) in nodes.iter().enumerate() {
            if node.leaf() {
                leaf_of[order[node.first as usize] as usize] = i as u32;
            }
        }
        let mut tree = Self {
            nodes,
            order,
            area_prefix,
            leaf_of,
            coherent: Vec::new(),
        };
        tree.coherent = tree.coherence(meshing, rays);
        tree
    }

    /// Which nodes are coherent: leaves are; a cluster is when
    /// [`COHERENCE_RAYS`] segments between points of its leaves (stratified over its
    /// leaves in tree order, each point lifted off its surface by the cluster's radius, over
    /// furniture, or halfway to the surface above it) are all open. A cluster of floor elements running under a wall into the
    /// next room is not: a far link would carry light through the wall to the elements on
    /// its far side (as receiver), or from them (as sender).
    pub(super) fn coherence(&self, meshing: &Meshing, rays: &RayScene) -> Vec<bool> {
        let els = &meshing.elements;
        let tree = self;
        tree.nodes
            .par_iter()
            .enumerate()
            .map(|(i, node)| {
                if node.leaf() {
                    return true;
                }
                let lift = COHERENCE_LIFT * node.radius;
                let mut rng = Rng::new(hash_seed(0xc0e7, i as u64, 0), 0x5e);
                // Lifted, but no further than halfway to the first surface above (a point
                // lifted through the ceiling would see over every wall).
                let lifted = |e: &crate::mesh::Element, x: Vec3| {
                    let room = rays
                        .closest_hit(x, e.normal, 1e-4 * lift, 2.0 * lift)
                        .map_or(lift, |h| 0.5 * h.t);
                    x + e.normal * lift.min(room)
                };
                let point = |u: f32, rng: &mut Rng| {
                    let e = &els[tree.leaf_at(node, u) as usize];
                    lifted(e, e.uniform_point(rng.next_vec2()))
                };
                if node.count <= STAR_LEAVES && node.nearly_flat() {
                    // Small flat clusters (pieces of a floor, which the element budget
                    // keeps whole): every leaf against the middle one by area. Random
                    // pairs would miss a small piece on the far side of a wall (a floor
                    // piece split at its foot). Clusters of furniture keep the random
                    // pairs: their parts hide each other from any one of them.
                    let hub = &els[tree.leaf_at(node, 0.5) as usize];
                    let centre = lifted(hub, hub.centroid);
                    let leaves =
                        &tree.order[node.first as usize..(node.first + node.count) as usize];
                    return leaves.iter().all(|&j| {
                        let e = &els[j as usize];
                        std::ptr::eq(e, hub)
                            || !visibility::segment_blocked(rays, centre, lifted(e, e.centroid))
                    });
                }
                (0..COHERENCE_RAYS).all(|p| {
                    let u = (p as f32 + rng.next_f32()) / (2 * COHERENCE_RAYS) as f32;
                    let a = point(u, &mut rng);
                    let b = point(u + 0.5, &mut rng);
                    !visibility::segment_blocked(rays, a, b)
                })
            })
            .collect()
    }
}

/// How far [`Tree::coherence`] lifts its points, in cluster radii (over tables and
/// books, not over walls).
pub(super) const COHERENCE_LIFT: f32 = 1.0;

/// The normal cone (radians) within which a cluster counts as one surface for the element
/// budget's coherence rules ([`Node::nearly_flat`]).
pub(super) const NEARLY_FLAT: f32 = 0.05;

/// Clusters of at most this many leaves are tested by [`Tree::coherence`] leaf by leaf.
pub(super) const STAR_LEAVES: u32 = 32;

/// Segments tested per larger cluster by `Tree::coherence`.
pub const COHERENCE_RAYS: u32 = 8;

impl Tree {
    /// The leaf (element id) of node `n` at area fraction `u` in `[0, 1)`.
    pub(super) fn leaf_at(&self, n: &Node, u: f32) -> u32 {
        let (a, b) = (n.first as usize, (n.first + n.count) as usize);
        let (lo, hi) = (self.area_prefix[a], self.area_prefix[b]);
        let target = lo + (hi - lo) * u as f64;
        let i = self.area_prefix[a + 1..=b].partition_point(|&s| s <= target);
        self.order[(a + i).min(b - 1)]
    }
}

/// Builds the node over `order[first..first + count]` (sorted by orientation class) and
/// its subtree in pre-order; returns its index.
pub(super) fn build_node(
    els: &[crate::mesh::Element],
    class: &[u32],
    order: &mut [u32],
    first: usize,
    count: usize,
    nodes: &mut Vec<Node>,
) -> u32 {
    let index = nodes.len();
    if count == 1 {
        let e = &els[order[first] as usize];
        let (lo, hi) = e.corners.iter().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(a, b), &c| (a.min(c), b.max(c)),
        );
        let normal = e.normal;
        let offsets = e.corners.map(|c| normal.dot(c));
        nodes.push(Node {
            first: first as u32,
            count: 1,
            children: [NONE; 2],
            centre: e.centroid,
            radius: e
                .corners
                .iter()
                .map(|c| c.distance(e.centroid))
                .fold(0.0, f32::max),
            lo,
            hi,
            normal,
            cone: 0.0,
            cone_sin_cos: [0.0, 1.0],
            plane: [
                offsets.iter().copied().fold(f32::MAX, f32::min),
                offsets.iter().copied().fold(f32::MIN, f32::max),
            ],
            area: e.area,
        });
        return index as u32;
    }
    nodes.push(Node {
        first: first as u32,
        count: count as u32,
        children: [NONE; 2],
        centre: Vec3::ZERO,
        radius: 0.0,
        lo: Vec3::ZERO,
        hi: Vec3::ZERO,
        normal: Vec3::ZERO,
        cone: 0.0,
        cone_sin_cos: [0.0, 1.0],
        plane: [0.0; 2],
        area: 0.0,
    });
    let range = first..first + count;
    let split = if class[first] != class[first + count - 1] {
        // Orientation classes first: the class boundary nearest the middle.
        let mid = first + count / 2;
        let mut best = (usize::MAX, first + 1);
        for i in range.clone().skip(1) {
            if class[i] != class[i - 1] && i.abs_diff(mid) < best.0 {
                best = (i.abs_diff(mid), i);
            }
        }
        best.1 - first
    } else {
        // Then space: the median along the longest axis of the centroids' bounds.
        let slice = &mut order[range.clone()];
        let (lo, hi) = slice.iter().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(a, b), &j| {
                let c = els[j as usize].centroid;
                (a.min(c), b.max(c))
            },
        );
        let axis = (hi - lo).max_position();
        let half = count / 2;
        slice.select_nth_unstable_by(half, |&a, &b| {
            let (ca, cb) = (els[a as usize].centroid, els[b as usize].centroid);
            ca[axis].total_cmp(&cb[axis]).then(a.cmp(&b))
        });
        half
    };
    let left = build_node(els, class, order, first, split, nodes);
    let right = build_node(els, class, order, first + split, count - split, nodes);
    let (l, r) = (nodes[left as usize], nodes[right as usize]);
    let area = l.area + r.area;
    let centre = (l.centre * l.area + r.centre * r.area) / area.max(f32::MIN_POSITIVE);
    let (lo, hi) = (l.lo.min(r.lo), l.hi.max(r.hi));
    let radius = (hi - centre).max(centre - lo).length();
    let sum = l.normal * l.area + r.normal * r.area;
    let (normal, cone) = if sum.length() > 1e-6 * area {
        let n = sum.normalize();
        let angle = |m: Vec3| n.dot(m).clamp(-1.0, 1.0).acos();
        let cone = (angle(l.normal) + l.cone).max(angle(r.normal) + r.cone);
        (n, cone.min(std::f32::consts::PI))
    } else {
        (Vec3::ZERO, std::f32::consts::PI)
    };
    let plane = if cone < 1e-4 {
        // Both children flat with (to rounding) this normal: their offsets compare.
        [l.plane[0].min(r.plane[0]), l.plane[1].max(r.plane[1])]
    } else {
        [0.0; 2]
    };
    nodes[index] = Node {
        first: first as u32,
        count: count as u32,
        children: [left, right],
        centre,
        radius,
        lo,
        hi,
        normal,
        cone,
        cone_sin_cos: [cone.sin(), cone.cos()],
        plane,
        area,
    };
    index as u32
}

/// How the leaves of node `a` see the region of node `b`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Facing {
    /// In front of (or on) every leaf's plane, not wholly on them.
    Front,
    /// Behind (or on) every leaf's plane: nothing passes.
    Behind,
    /// Neither.
    Mixed,
}

/// `b_corners`: `b`'s triangle when `b` is a leaf (its box would straddle planes that the
/// triangle does not: a tilted element beside a floor).
pub(super) fn facing(a: &Node, b: &Node, b_corners: Option<&[Vec3; 3]>, tol: f32) -> Facing {
    if a.flat() {
        // b's box (or triangle) against a's planes, exactly.
        let n = a.normal;
        let (mut min, mut max) = (0.0f32, 0.0f32);
        if let Some(c) = b_corners {
            let d = c.map(|x| n.dot(x));
            min = d[0].min(d[1]).min(d[2]);
            max = d[0].max(d[1]).max(d[2]);
        } else {
            for i in 0..3 {
                let (p, q) = (n[i] * b.lo[i], n[i] * b.hi[i]);
                min += p.min(q);
                max += p.max(q);
            }
        }
        // Behind is tested first: a node lying in `a`'s plane (the floor beside a floor)
        // is seen edge-on by every leaf of `a` and gets nothing.
        if max <= a.plane[0] + tol {
            Facing::Behind
        } else if min >= a.plane[1] - tol {
            Facing::Front
        } else {
            Facing::Mixed
        }
    } else {
        let d = b.centre - a.centre;
        let dist = d.length();
        let reach = a.radius + b.radius;
        if a.normal == Vec3::ZERO || dist <= reach {
            return Facing::Mixed;
        }
        // With `beta = asin(reach / dist)` the half-angle `b` subtends and `angle` that of
        // its centre from `a.normal`: Front when `angle + cone + beta < pi / 2`, Behind
        // when `angle - cone - beta > pi / 2`, compared through cosines (no inverse
        // trigonometry in the refinement's inner loop).
        let sb = reach / dist;
        let cb = (1.0 - sb * sb).max(0.0).sqrt();
        let [sc, cc] = a.cone_sin_cos;
        let (sin_phi, cos_phi) = (sc * cb + cc * sb, cc * cb - sc * sb);
        let cos_angle = a.normal.dot(d / dist);
        if cos_phi <= 0.0 {
            Facing::Mixed
        } else if cos_angle > sin_phi {
            Facing::Front
        } else if cos_angle < -sin_phi {
            Facing::Behind
        } else {
            Facing::Mixed
        }
    }
}
