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
    /// Per node, whether its leaves lie in one group of the element budget
    /// ([`Meshing::groups`]); empty when every element is a group of its own. A grouped
    /// tree has each group as one subtree ([`Tree::grouped`]).
    pub(super) in_group: Vec<bool>,
    /// Each leaf's geometry in leaf order (`leaves[i]` is element `order[i]`), so that the
    /// refinement's samples read a cluster's leaves from one contiguous run instead of
    /// gathering them from the elements' records (176 bytes each, in the file's order):
    /// on the Breakfast Room at 4 096 asked those loads were a fifth of the solve. Empty
    /// for a tree built only for its nodes ([`Tree::nodes_only`]).
    pub(super) leaves: Vec<Leaf>,
}

/// What the refinement reads of a leaf ([`Tree::leaves`]): its element's corners, normal
/// and area, and the element's id.
#[derive(Clone, Copy, Debug)]
pub(super) struct Leaf {
    pub(super) corners: [Vec3; 3],
    pub(super) normal: Vec3,
    pub(super) area: f32,
    pub(super) element: u32,
}

impl Leaf {
    fn of(e: &crate::mesh::Element, element: u32) -> Self {
        Self {
            corners: e.corners,
            normal: e.normal,
            area: e.area,
            element,
        }
    }

    /// The point-to-point kernel `max(cos_x, 0) max(cos_q, 0) / (pi r^2)` from `x` (unit
    /// normal `n`) to the point `q` of the leaf that `u` draws uniformly, and `q`: times
    /// the leaf's area, an unbiased estimate of the unoccluded form factor from `x` to the
    /// leaf (zero where `q` is below `x`'s horizon or `x` behind the leaf).
    pub(super) fn kernel(&self, x: Vec3, n: Vec3, u: glam::Vec2) -> (f32, Vec3) {
        let q = self.uniform_point(u);
        let d = q - x;
        let r2 = d.length_squared();
        let (cx, cq) = (n.dot(d), -self.normal.dot(d));
        if cx <= 0.0 || cq <= 0.0 || r2 <= 0.0 {
            return (0.0, q);
        }
        (cx * cq / (std::f32::consts::PI * r2 * r2), q)
    }

    /// A point uniform over the leaf (as [`crate::mesh::Element::uniform_point`]).
    pub(super) fn uniform_point(&self, u: glam::Vec2) -> Vec3 {
        crate::mesh::uniform_point_on(&self.corners, u)
    }
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
    /// `rays`; with each of [`Meshing::groups`] one subtree where `by_group`
    /// ([`Tree::grouped`]).
    pub(super) fn build(meshing: &Meshing, rays: &RayScene, by_group: bool) -> Self {
        let mut tree = if by_group {
            Self::grouped(meshing)
        } else {
            Self::nodes_only(meshing, false)
        };
        tree.coherent = tree.coherence(meshing, rays);
        let els = &meshing.elements;
        tree.leaves = tree
            .order
            .iter()
            .map(|&j| Leaf::of(&els[j as usize], j))
            .collect();
        tree
    }

    /// The tree without its coherence (left empty). `on_grid`: the spatial splits compare
    /// the centroids on a grid of 2^-20 of their bounds, so that the same scene in other
    /// units (coordinates rounded otherwise) builds the same tree, as the element budget's
    /// groups must be; otherwise as floats (the solve's tree).
    pub(super) fn nodes_only(meshing: &Meshing, on_grid: bool) -> Self {
        let els = &meshing.elements;
        let mut keyed: Vec<(u32, u32)> = (0..els.len() as u32)
            .filter(|&j| in_tree(&els[j as usize]))
            .map(|j| (orientation_class(els[j as usize].normal), j))
            .collect();
        keyed.sort_unstable();
        let class: Vec<u32> = keyed.iter().map(|k| k.0).collect();
        let mut order: Vec<u32> = keyed.iter().map(|k| k.1).collect();
        let mut nodes = Vec::with_capacity(2 * order.len());
        if !order.is_empty() {
            let count = order.len();
            let (lo, hi) = order.iter().fold(
                (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
                |(a, b), &j| {
                    let c = els[j as usize].centroid;
                    (a.min(c), b.max(c))
                },
            );
            let step = ((hi - lo).max_element() / (1 << 20) as f32).max(f32::MIN_POSITIVE);
            let keys: Vec<[i32; 3]> = if on_grid {
                els.iter()
                    .map(|e| {
                        let q = ((e.centroid - lo) / step).round();
                        [q.x as i32, q.y as i32, q.z as i32]
                    })
                    .collect()
            } else {
                Vec::new()
            };
            let keys = on_grid.then_some(keys.as_slice());
            build_node(els, keys, &class, &mut order, 0, count, &mut nodes);
        }
        Self::with_nodes(els, nodes, order, Vec::new())
    }

    /// The solve's tree when the element budget grouped the elements
    /// ([`Meshing::groups`]): each group is one subtree (its leaves by orientation, then
    /// in space, as [`Tree::nodes_only`] orders them), and above the groups the tree
    /// splits them likewise, by the orientation class of each group's mean normal, then at
    /// the median of their centroids along the longest axis. The reflected light's links
    /// then end at a group or above ([`Tree::in_group`]): the solve is as large as the
    /// solution, not as the file.
    pub(super) fn grouped(meshing: &Meshing) -> Self {
        let els = &meshing.elements;
        let groups = &meshing.groups;
        let mut members: Vec<Vec<(u32, u32)>> = vec![Vec::new(); groups.count];
        for (j, e) in els.iter().enumerate() {
            if in_tree(e) {
                members[groups.of(j)].push((orientation_class(e.normal), j as u32));
            }
        }
        let mut units: Vec<Unit> = members
            .iter_mut()
            .enumerate()
            .filter(|(_, m)| !m.is_empty())
            .map(|(g, m)| {
                m.sort_unstable();
                let (mut area, mut centre, mut normal) = (0.0f64, glam::DVec3::ZERO, Vec3::ZERO);
                for &(_, j) in m.iter() {
                    let e = &els[j as usize];
                    area += e.area as f64;
                    centre += e.centroid.as_dvec3() * e.area as f64;
                    normal += e.normal * e.area;
                }
                let class = if normal.length() > 1e-6 * area as f32 {
                    orientation_class(normal)
                } else {
                    MIXED_CLASS
                };
                Unit {
                    group: g as u32,
                    class,
                    centre: (centre / area.max(f64::MIN_POSITIVE)).as_vec3(),
                }
            })
            .collect();
        units.sort_unstable_by_key(|u| (u.class, u.group));
        let shape = partition_units(&mut units);
        let mut order = Vec::with_capacity(els.len());
        let mut class = Vec::with_capacity(els.len());
        let mut starts = Vec::with_capacity(units.len() + 1);
        for u in &units {
            starts.push(order.len());
            for &(c, j) in &members[u.group as usize] {
                order.push(j);
                class.push(c);
            }
        }
        starts.push(order.len());
        let mut nodes = Vec::with_capacity(2 * order.len());
        let mut in_group = Vec::with_capacity(2 * order.len());
        if !units.is_empty() {
            let mut build = GroupedBuild {
                els,
                class: &class,
                order: &mut order,
                starts: &starts,
                nodes: &mut nodes,
                in_group: &mut in_group,
            };
            build.node(&shape, 0, units.len());
        }
        Self::with_nodes(els, nodes, order, in_group)
    }

    /// The tree of `nodes` over `order`, with its area prefix sums and leaf table.
    fn with_nodes(
        els: &[crate::mesh::Element],
        nodes: Vec<Node>,
        order: Vec<u32>,
        in_group: Vec<bool>,
    ) -> Self {
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
        Self {
            nodes,
            order,
            area_prefix,
            leaf_of,
            coherent: Vec::new(),
            in_group,
            leaves: Vec::new(),
        }
    }

    /// Which nodes are coherent: leaves are; a cluster is when
    /// [`COHERENCE_RAYS`] segments between points of its leaves (stratified over its
    /// leaves in tree order, each point lifted off its surface by the cluster's radius, over
    /// furniture, or halfway to the surface above it) are all open. A cluster of floor elements running under a wall into the
    /// next room is not: a far link would carry light through the wall to the elements on
    /// its far side (as receiver), or from them (as sender).
    pub(super) fn coherence(&self, meshing: &Meshing, rays: &RayScene) -> Vec<bool> {
        (0..self.nodes.len())
            .into_par_iter()
            .map(|i| self.node_coherent(i, meshing, rays, STAR_LEAVES))
            .collect()
    }

    /// Whether node `i` is coherent ([`Tree::coherence`]), with nearly flat clusters of up
    /// to `star_leaves` leaves tested leaf by leaf.
    pub(super) fn node_coherent(
        &self,
        i: usize,
        meshing: &Meshing,
        rays: &RayScene,
        star_leaves: u32,
    ) -> bool {
        let els = &meshing.elements;
        let tree = self;
        let node = &tree.nodes[i];
        {
            {
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
                if node.count <= star_leaves && node.nearly_flat() {
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
            }
        }
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

/// Parts found by sight in one node of the element budget's cut ([`Tree::sight_parts`]).
pub(super) const SIGHT_HUBS: usize = 8;

/// Segments tested per larger cluster by `Tree::coherence`.
pub const COHERENCE_RAYS: u32 = 8;

impl Tree {
    /// The leaf (element id) of node `n` at area fraction `u` in `[0, 1)`.
    pub(super) fn leaf_at(&self, n: &Node, u: f32) -> u32 {
        self.order[self.slot_at(n, u)]
    }

    /// The leaf of node `n` at area fraction `u` ([`Tree::leaf_at`]) as its geometry
    /// ([`Tree::leaves`], which [`Tree::build`] fills).
    pub(super) fn leaf(&self, n: &Node, u: f32) -> &Leaf {
        &self.leaves[self.slot_at(n, u)]
    }

    /// The position in leaf order of [`Tree::leaf_at`]'s leaf.
    fn slot_at(&self, n: &Node, u: f32) -> usize {
        let (a, b) = (n.first as usize, (n.first + n.count) as usize);
        let (lo, hi) = (self.area_prefix[a], self.area_prefix[b]);
        let target = lo + (hi - lo) * u as f64;
        let i = self.area_prefix[a + 1..=b].partition_point(|&s| s <= target);
        (a + i).min(b - 1)
    }
}

/// Builds the node over `order[first..first + count]` (sorted by orientation class) and
/// its subtree in pre-order; returns its index.
pub(super) fn build_node(
    els: &[crate::mesh::Element],
    keys: Option<&[[i32; 3]]>,
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
    nodes.push(Node::placeholder(first, count));
    let range = first..first + count;
    let split = if let Some(at) = class_split(&class[range.clone()]) {
        // Orientation classes first.
        at
    } else {
        // Then space: the median along the longest axis of the centroids' bounds (on
        // their grid, the first axis of equal extents).
        let slice = &mut order[range.clone()];
        let half = count / 2;
        if let Some(keys) = keys {
            let (lo, hi) = slice
                .iter()
                .fold(([i32::MAX; 3], [i32::MIN; 3]), |(a, b), &j| {
                    let k = keys[j as usize];
                    (
                        [a[0].min(k[0]), a[1].min(k[1]), a[2].min(k[2])],
                        [b[0].max(k[0]), b[1].max(k[1]), b[2].max(k[2])],
                    )
                });
            let extent = [0, 1, 2].map(|i| hi[i] as i64 - lo[i] as i64);
            let axis = (0..3).fold(0, |best, i| if extent[i] > extent[best] { i } else { best });
            slice.select_nth_unstable_by_key(half, |&j| (keys[j as usize][axis], j));
        } else {
            let (lo, hi) = slice.iter().fold(
                (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
                |(a, b), &j| {
                    let c = els[j as usize].centroid;
                    (a.min(c), b.max(c))
                },
            );
            let axis = (hi - lo).max_position();
            slice.select_nth_unstable_by(half, |&a, &b| {
                let (ca, cb) = (els[a as usize].centroid, els[b as usize].centroid);
                ca[axis].total_cmp(&cb[axis]).then(a.cmp(&b))
            });
        }
        half
    };
    let left = build_node(els, keys, class, order, first, split, nodes);
    let right = build_node(els, keys, class, order, first + split, count - split, nodes);
    join(nodes, index, left, right);
    index as u32
}

impl Node {
    /// A cluster over `order[first..first + count]` whose bounds [`join`] fills in.
    fn placeholder(first: usize, count: usize) -> Self {
        Node {
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
        }
    }
}

/// Makes node `index` (a placeholder) the parent of nodes `left` and `right`: its area,
/// centroid, bounds, normal cone and plane from theirs.
fn join(nodes: &mut [Node], index: usize, left: u32, right: u32) {
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
        first: nodes[index].first,
        count: nodes[index].count,
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

/// The element budget's groups ([`crate::mesh::ElementGroups`]): at most `cap` sets of
/// leaves covering every leaf, each a group of mesh elements that the solution holds one
/// value for. First a cut through the tree: top down, the largest node (by its area,
/// doubled where its leaves face different ways, [`Node::nearly_flat`], or by twice its
/// radius squared where it is spread thin: the door frames along a corridor, all facing
/// one way) is split while the cut holds at most `target` nodes. Then each nearly flat
/// node of the cut is parted by sight ([`Tree::sight_parts`]): a floor piece whose leaves
/// lie on both sides of a wall becomes two groups, so that no group spreads light through
/// a wall, as long as the groups stay within `cap` (the largest parts first).
/// Returns each element's group, [`NONE`] for those outside the tree (hidden, or of no
/// area), and the number of groups.
pub(crate) fn budget_cut(
    meshing: &Meshing,
    rays: Option<&RayScene>,
    target: usize,
    cap: usize,
) -> (Vec<u32>, usize) {
    let tree = Tree::nodes_only(meshing, true);
    let mut of_element = vec![NONE; meshing.elements.len()];
    if tree.nodes.is_empty() {
        return (of_element, 0);
    }
    let cut = tree.size_cut(target.max(1));
    let node_parts: Vec<Vec<Vec<u32>>> = cut
        .par_iter()
        .map(|&i| match rays {
            Some(r) => tree.sight_parts(i as usize, meshing, r),
            None => {
                let n = &tree.nodes[i as usize];
                vec![tree.order[n.first as usize..(n.first + n.count) as usize].to_vec()]
            }
        })
        .collect();
    // Every node keeps its first part; of the others, the largest by area are groups of
    // their own while the groups stay within `cap`, and the rest go back to their node's
    // first part (what then still reaches through a wall is the smallest).
    let area = |part: &[u32]| -> f64 {
        part.iter()
            .map(|&j| meshing.elements[j as usize].area as f64)
            .sum()
    };
    let mut extra: Vec<(f64, usize, usize)> = node_parts
        .iter()
        .enumerate()
        .flat_map(|(n, parts)| (1..parts.len()).map(move |p| (n, p)))
        .map(|(n, p)| (area(&node_parts[n][p]), n, p))
        .collect();
    extra.sort_by(|a, b| b.0.total_cmp(&a.0).then((a.1, a.2).cmp(&(b.1, b.2))));
    let room = cap.saturating_sub(cut.len());
    let mut own = vec![Vec::<bool>::new(); node_parts.len()];
    for (n, parts) in node_parts.iter().enumerate() {
        own[n] = vec![false; parts.len()];
        own[n][0] = true;
    }
    for &(_, n, p) in extra.iter().take(room) {
        own[n][p] = true;
    }
    let mut parts: Vec<Vec<u32>> = Vec::new();
    for (n, node) in node_parts.into_iter().enumerate() {
        let first = parts.len();
        for (p, part) in node.into_iter().enumerate() {
            if own[n][p] {
                parts.push(part);
            } else {
                parts[first].extend(part);
            }
        }
    }
    for (g, part) in parts.iter().enumerate() {
        for &j in part {
            of_element[j as usize] = g as u32;
        }
    }
    (of_element, parts.len())
}

impl Tree {
    /// At most `target` nodes covering every leaf, in leaf order ([`budget_cut`]).
    fn size_cut(&self, target: usize) -> Vec<u32> {
        use std::cmp::Reverse;
        use std::collections::BinaryHeap;
        let size = |node: &Node| {
            let weight = if node.nearly_flat() { 1.0 } else { 2.0 };
            (node.area as f64 * weight).max(2.0 * node.radius as f64 * node.radius as f64)
        };
        // (priority, node): a max-heap, ties broken towards the lower node. The priority is
        // the size over the root's in steps of 2^-16, so that the same scene in other
        // units (sizes rounded otherwise) is cut alike.
        let total = size(&self.nodes[0]).max(f64::MIN_POSITIVE);
        let entry = |i: u32| {
            let share = size(&self.nodes[i as usize]) / total;
            let priority = if share.is_finite() {
                (share.clamp(0.0, 1.0) * 2f64.powi(16)).round() as u64
            } else {
                u64::MAX
            };
            (priority, Reverse(i))
        };
        let mut heap = BinaryHeap::new();
        heap.push(entry(0));
        let mut kept: Vec<u32> = Vec::new();
        while let Some((_, Reverse(i))) = heap.pop() {
            let node = &self.nodes[i as usize];
            if node.leaf() || heap.len() + kept.len() + 2 > target {
                kept.push(i);
                continue;
            }
            let [a, b] = node.children;
            heap.push(entry(a));
            heap.push(entry(b));
        }
        kept.sort_unstable_by_key(|&i| self.nodes[i as usize].first);
        kept
    }

    /// The leaves of node `i` in parts that see each other: for a nearly flat node, the
    /// leaves whose centroids (lifted as [`Tree::coherence`] lifts them) the middle leaf
    /// by area sees, then of the rest those the largest of them sees, and so on for
    /// [`SIGHT_HUBS`] parts, the rest one more; any other node whole (a chair's parts hide
    /// each other and stay one group).
    pub(super) fn sight_parts(
        &self,
        i: usize,
        meshing: &Meshing,
        rays: &RayScene,
    ) -> Vec<Vec<u32>> {
        let els = &meshing.elements;
        let node = &self.nodes[i];
        let leaves = &self.order[node.first as usize..(node.first + node.count) as usize];
        if node.leaf() || !node.nearly_flat() {
            return vec![leaves.to_vec()];
        }
        let lift = COHERENCE_LIFT * node.radius;
        let points: Vec<Vec3> = leaves
            .iter()
            .map(|&j| {
                let e = &els[j as usize];
                let room = rays
                    .closest_hit(e.centroid, e.normal, 1e-4 * lift, 2.0 * lift)
                    .map_or(lift, |h| 0.5 * h.t);
                e.centroid + e.normal * lift.min(room)
            })
            .collect();
        let middle = self.leaf_at(node, 0.5);
        let mut hub = leaves.iter().position(|&j| j == middle).unwrap_or(0);
        let mut rest: Vec<usize> = (0..leaves.len()).collect();
        let mut parts: Vec<Vec<u32>> = Vec::new();
        loop {
            if parts.len() == SIGHT_HUBS {
                // What no hub saw: one part (a floor among hundreds of books).
                parts.push(rest.iter().map(|&x| leaves[x]).collect());
                return parts;
            }
            let (seen, unseen): (Vec<usize>, Vec<usize>) = rest.iter().partition(|&&x| {
                x == hub || !visibility::segment_blocked(rays, points[hub], points[x])
            });
            parts.push(seen.iter().map(|&x| leaves[x]).collect());
            if unseen.is_empty() {
                return parts;
            }
            rest = unseen;
            hub = *rest
                .iter()
                .max_by(|&&a, &&b| {
                    let (ea, eb) = (&els[leaves[a] as usize], &els[leaves[b] as usize]);
                    ea.area.total_cmp(&eb.area).then(b.cmp(&a))
                })
                .unwrap_or(&rest[0]);
        }
    }
}

/// Whether an element is a leaf of the tree: open and of finite, positive area.
fn in_tree(e: &crate::mesh::Element) -> bool {
    !e.hidden && e.area > 0.0 && e.area.is_finite()
}

/// The orientation class of a group whose normals cancel (after the 54 of
/// [`orientation_class`]).
const MIXED_CLASS: u32 = 54;

/// A group of the element budget as [`Tree::grouped`] places it.
struct Unit {
    group: u32,
    class: u32,
    centre: Vec3,
}

/// How [`Tree::grouped`] splits the groups above them: one group, or the first `n` and
/// the rest.
enum Shape {
    Group,
    Split(usize, Box<Shape>, Box<Shape>),
}

/// Where a run of items sorted by orientation class splits first: the class boundary
/// nearest the middle (`None` when they are all of one class).
fn class_split(class: &[u32]) -> Option<usize> {
    let mid = class.len() / 2;
    (1..class.len())
        .filter(|&i| class[i] != class[i - 1])
        .min_by_key(|&i| i.abs_diff(mid))
}

/// Orders `units` (sorted by class) into the tree above the groups: the class boundary
/// nearest the middle, then the median along the longest axis of the centroids.
fn partition_units(units: &mut [Unit]) -> Shape {
    let count = units.len();
    if count <= 1 {
        return Shape::Group;
    }
    let classes: Vec<u32> = units.iter().map(|u| u.class).collect();
    let split = if let Some(at) = class_split(&classes) {
        at
    } else {
        let (lo, hi) = units.iter().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(a, b), u| (a.min(u.centre), b.max(u.centre)),
        );
        let axis = (hi - lo).max_position();
        let half = count / 2;
        units.select_nth_unstable_by(half, |a, b| {
            a.centre[axis]
                .total_cmp(&b.centre[axis])
                .then(a.group.cmp(&b.group))
        });
        half
    };
    let (a, b) = units.split_at_mut(split);
    Shape::Split(
        split,
        Box::new(partition_units(a)),
        Box::new(partition_units(b)),
    )
}

/// The state of [`Tree::grouped`]'s node building.
struct GroupedBuild<'a> {
    els: &'a [crate::mesh::Element],
    class: &'a [u32],
    order: &'a mut [u32],
    /// Where each placed group's leaves start in `order` (and the end).
    starts: &'a [usize],
    nodes: &'a mut Vec<Node>,
    in_group: &'a mut Vec<bool>,
}

impl GroupedBuild<'_> {
    /// Builds the node over placed groups `first..first + count` of `shape`; returns its
    /// index.
    fn node(&mut self, shape: &Shape, first: usize, count: usize) -> u32 {
        let (a, b) = (self.starts[first], self.starts[first + count]);
        match shape {
            Shape::Group => {
                let index =
                    build_node(self.els, None, self.class, self.order, a, b - a, self.nodes);
                self.in_group.resize(self.nodes.len(), true);
                index
            }
            Shape::Split(n, left, right) => {
                let index = self.nodes.len();
                self.nodes.push(Node::placeholder(a, b - a));
                self.in_group.push(false);
                let l = self.node(left, first, *n);
                let r = self.node(right, first + n, count - n);
                join(self.nodes, index, l, r);
                index as u32
            }
        }
    }
}
