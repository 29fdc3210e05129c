//! A four-wide BVH laid out for CPU ray queries: the tree [`crate::ray::RayScene`] traverses.
//!
//! obvhs builds the binary tree (PLOC, reinsertion, spatial pre-splits); this module folds it
//! into nodes of four children whose boxes are stored as structures of arrays, and packs the
//! triangles of each leaf four to a packet. One ray then tests a node's four boxes, or a
//! leaf's four triangles, in a handful of four-lane vector operations (`glam::Vec4`: SSE on
//! x86, NEON on ARM, scalar elsewhere), and visits the hit children nearest first so a closest
//! hit shrinks the ray early. obvhs' own compressed eight-wide tree (CWBVH) is laid out for
//! GPUs: its byte-quantised boxes cost a conversion per child on a CPU, and it orders children
//! by the ray's octant rather than by distance. On the Breakfast Room this tree traces
//! closest-hit rays 1.3x and shadow rays 1.7x as fast; on a box field of random rays both
//! trace at the same rate (docs/reference.md has the figures).
//!
//! The box test is the slab test with the far distance widened by `1 + 2 gamma(3)` (Ize,
//! "Robust BVH Ray Traversal", JCGT 2013), so rounding never culls a box a ray touches. The
//! triangle test is Moeller and Trumbore's, evaluated with the same operations in the same
//! order as the scalar test the brute-force oracle uses, so both accept the same hits.

use glam::{BVec4A, Vec3A, Vec4};
use obvhs::{BvhBuildParams, bvh2::builder::build_bvh2_from_tris, triangle::Triangle};

/// Most triangles in one leaf: one packet.
const LEAF_MAX: u32 = 4;
/// A child reference with this bit set is a leaf (the low bits index `packets`).
const LEAF_BIT: u32 = 1 << 31;
/// A child slot with nothing in it.
const EMPTY: u32 = u32::MAX;
/// Entries of the fixed traversal stack; deeper trees take a growable one.
const STACK: usize = 64;
/// `1 + 2 gamma(3)` with `gamma(n) = n eps / (1 - n eps)`, `eps = 2^-24` (Ize 2013).
const FAR_WIDEN: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// Four children: their boxes as lanes, and what each is.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Node {
    /// Lower corners: x, y and z of the four children.
    lo: [Vec4; 3],
    /// Upper corners.
    hi: [Vec4; 3],
    /// An inner node's index, `LEAF_BIT | packet`, or `EMPTY`.
    child: [u32; 4],
    /// The lanes that hold a child, as a mask: the traversal never enters an `EMPTY` slot,
    /// whatever its box test gives (an infinite or overflowing coordinate makes the slab
    /// distances of an empty box NaN, which the lane minimum and maximum can drop).
    used: u32,
}

impl Node {
    /// No children: boxes that no ray enters.
    fn empty() -> Self {
        Self {
            lo: [Vec4::INFINITY; 3],
            hi: [Vec4::NEG_INFINITY; 3],
            child: [EMPTY; 4],
            used: 0,
        }
    }

    fn set(&mut self, slot: usize, lo: Vec3A, hi: Vec3A, child: u32) {
        for a in 0..3 {
            self.lo[a][slot] = lo[a];
            self.hi[a][slot] = hi[a];
        }
        self.child[slot] = child;
        if child == EMPTY {
            self.used &= !(1 << slot);
        } else {
            self.used |= 1 << slot;
        }
    }
}

/// Four triangles as lanes: a vertex and two edges each.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
struct Packet {
    v0: [Vec4; 3],
    e1: [Vec4; 3],
    e2: [Vec4; 3],
    /// The caller's triangle id per lane (unused lanes are degenerate and never hit).
    id: [u32; 4],
}

/// A ray as the traversal uses it: each coordinate splat over four lanes.
pub(crate) struct PreparedRay {
    origin: [Vec4; 3],
    direction: [Vec4; 3],
    /// `1 / direction` (unused along `parallel` axes).
    inv: [Vec4; 3],
    negative: [bool; 3],
    /// The direction's component is zero (or too small to invert) along this axis.
    parallel: [bool; 3],
    t_min: f32,
    t_max: f32,
}

impl PreparedRay {
    pub(crate) fn new(origin: Vec3A, direction: Vec3A, t_min: f32, t_max: f32) -> Self {
        let parallel = [0, 1, 2].map(|a| direction[a].abs() <= 1e-30);
        let inv = [0, 1, 2].map(|a| if parallel[a] { 0.0 } else { 1.0 / direction[a] });
        Self {
            parallel,
            origin: [0, 1, 2].map(|a| Vec4::splat(origin[a])),
            direction: [0, 1, 2].map(|a| Vec4::splat(direction[a])),
            inv: inv.map(Vec4::splat),
            negative: inv.map(|i| i < 0.0),
            t_min,
            t_max,
        }
    }

    /// Which of `node`'s children the ray enters within `[t_min, t_max]` (boxes closed), as a lane mask,
    /// and the entry distances.
    #[inline(always)]
    fn boxes(&self, node: &Node, t_max: f32) -> (u32, Vec4) {
        let mut near = Vec4::splat(self.t_min);
        let mut far = Vec4::splat(f32::INFINITY);
        let mut inside = BVec4A::splat(true);
        for a in 0..3 {
            if self.parallel[a] {
                // No slab distances along an axis the ray does not move on: the ray is in
                // the slab for every `t` or for none (a ray on a box's face is in it).
                inside &= node.lo[a].cmple(self.origin[a]) & self.origin[a].cmple(node.hi[a]);
                continue;
            }
            let (n, f) = if self.negative[a] {
                (node.hi[a], node.lo[a])
            } else {
                (node.lo[a], node.hi[a])
            };
            near = near.max((n - self.origin[a]) * self.inv[a]);
            far = far.min((f - self.origin[a]) * self.inv[a]);
        }
        let far = (far * FAR_WIDEN).min(Vec4::splat(t_max));
        ((near.cmple(far) & inside).bitmask() & node.used, near)
    }

    /// Moeller-Trumbore on four triangles: which lanes hit with `t` in the ray's
    /// `[t_min, t_max)` and at most `t_max` (the nearest hit so far), and each lane's `t`, `u`
    /// and `v`. Lane for lane the same operations as [`intersect_one`].
    #[inline(always)]
    fn triangles(&self, p: &Packet, t_max: f32) -> (BVec4A, Vec4, Vec4, Vec4) {
        let [dx, dy, dz] = self.direction;
        let [ax, ay, az] = p.e1;
        let [bx, by, bz] = p.e2;
        let px = dy * bz - dz * by;
        let py = dz * bx - dx * bz;
        let pz = dx * by - dy * bx;
        let det = ax * px + ay * py + az * pz;
        let inv = Vec4::ONE / det;
        let sx = self.origin[0] - p.v0[0];
        let sy = self.origin[1] - p.v0[1];
        let sz = self.origin[2] - p.v0[2];
        let u = (sx * px + sy * py + sz * pz) * inv;
        let qx = sy * az - sz * ay;
        let qy = sz * ax - sx * az;
        let qz = sx * ay - sy * ax;
        let v = (dx * qx + dy * qy + dz * qz) * inv;
        let t = (bx * qx + by * qy + bz * qz) * inv;
        let valid = det.cmpne(Vec4::ZERO)
            & det.abs().cmplt(Vec4::INFINITY)
            & u.cmpge(Vec4::ZERO)
            & u.cmple(Vec4::ONE)
            & v.cmpge(Vec4::ZERO)
            & (u + v).cmple(Vec4::ONE)
            & t.cmpge(Vec4::splat(self.t_min))
            & t.cmplt(Vec4::splat(self.t_max))
            & t.cmple(Vec4::splat(t_max));
        (valid, t, u, v)
    }
}

/// Moeller-Trumbore on one triangle (vertex `v0`, edges `e1`, `e2`), two-sided: `(t, u, v)`
/// for a hit with `t` in `[t_min, t_max)` (a hit exactly at `t_max` is not one: a segment
/// that ends on a surface is not blocked by it). The brute-force oracle's test, and lane for lane
/// what the packets compute.
#[inline]
pub(crate) fn intersect_one(
    v0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
    origin: Vec3A,
    d: Vec3A,
    t_min: f32,
    t_max: f32,
) -> Option<(f32, f32, f32)> {
    let px = d.y * e2.z - d.z * e2.y;
    let py = d.z * e2.x - d.x * e2.z;
    let pz = d.x * e2.y - d.y * e2.x;
    let det = e1.x * px + e1.y * py + e1.z * pz;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = origin - v0;
    let u = (s.x * px + s.y * py + s.z * pz) * inv;
    let qx = s.y * e1.z - s.z * e1.y;
    let qy = s.z * e1.x - s.x * e1.z;
    let qz = s.x * e1.y - s.y * e1.x;
    let v = (d.x * qx + d.y * qy + d.z * qz) * inv;
    let t = (e2.x * qx + e2.y * qy + e2.z * qz) * inv;
    let hit = (0.0..=1.0).contains(&u) && v >= 0.0 && u + v <= 1.0 && t >= t_min && t < t_max;
    hit.then_some((t, u, v))
}

/// A closest hit: the caller's triangle id, distance and barycentrics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Found {
    pub id: u32,
    pub t: f32,
    pub u: f32,
    pub v: f32,
}

/// The traversal stack: child references with their entry distances.
trait Stack {
    fn push(&mut self, node: u32, t: f32);
    fn pop(&mut self) -> Option<(u32, f32)>;
}

struct ArrayStack {
    items: [(u32, f32); STACK],
    len: usize,
}

impl ArrayStack {
    #[inline(always)]
    fn new() -> Self {
        Self {
            items: [(0, 0.0); STACK],
            len: 0,
        }
    }
}

impl Stack for ArrayStack {
    #[inline(always)]
    fn push(&mut self, node: u32, t: f32) {
        // The tree's depth was checked at build time: `Bvh4::deep` trees use `Vec`.
        self.items[self.len] = (node, t);
        self.len += 1;
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, f32)> {
        self.len = self.len.checked_sub(1)?;
        Some(self.items[self.len])
    }
}

impl Stack for Vec<(u32, f32)> {
    fn push(&mut self, node: u32, t: f32) {
        Vec::push(self, (node, t));
    }
    fn pop(&mut self) -> Option<(u32, f32)> {
        Vec::pop(self)
    }
}

/// The four-wide tree over a set of triangles.
pub(crate) struct Bvh4 {
    nodes: Vec<Node>,
    packets: Vec<Packet>,
    /// The stack a traversal may need exceeds [`STACK`].
    deep: bool,
}

impl Bvh4 {
    /// Builds obvhs' binary tree with `params` (one triangle per leaf: the packets do the
    /// leaf sizing) over `tris`, and folds it; a hit on `tris[i]` reports id `i`.
    pub(crate) fn build(tris: &[Triangle], params: BvhBuildParams) -> Self {
        let params = BvhBuildParams {
            max_prims_per_leaf: 1,
            post_collapse_reinsertion_batch_ratio_multiplier: 0.0,
            ..params
        };
        let mut core = std::time::Duration::ZERO;
        let b2 = build_bvh2_from_tris(tris, params, &mut core);
        let n = b2.nodes.len();
        // Triangles under each binary node, children before parents.
        let mut order = Vec::with_capacity(n);
        let mut todo = vec![0usize];
        while let Some(i) = todo.pop() {
            order.push(i);
            let node = &b2.nodes[i];
            if !node.is_leaf() {
                todo.push(node.first_index as usize);
                todo.push(node.first_index as usize + 1);
            }
        }
        let mut count = vec![0u32; n];
        for &i in order.iter().rev() {
            let node = &b2.nodes[i];
            count[i] = if node.is_leaf() {
                node.prim_count
            } else {
                let c = node.first_index as usize;
                count[c].saturating_add(count[c + 1])
            };
        }
        // A binary node whose triangles become one leaf.
        let packs = |k: usize| b2.nodes[k].is_leaf() || count[k] <= LEAF_MAX;
        let mut this = Self {
            nodes: vec![Node::empty()],
            packets: Vec::new(),
            deep: false,
        };
        // (binary node, four-wide node it fills)
        let mut work: Vec<(usize, usize)> = Vec::new();
        let root = &b2.nodes[0];
        if packs(0) {
            let leaf = this.leaf(&b2, 0, tris);
            this.nodes[0].set(0, root.aabb().min, root.aabb().max, leaf);
        } else {
            work.push((0, 0));
        }
        while let Some((b, at)) = work.pop() {
            // Open the largest child until there are four or none can open.
            let first = b2.nodes[b].first_index as usize;
            let mut kids = vec![first, first + 1];
            while kids.len() < 4 {
                let open = kids
                    .iter()
                    .enumerate()
                    .filter(|&(_, &k)| !packs(k))
                    .max_by(|a, b| {
                        let area = |k: usize| b2.nodes[k].aabb().half_area();
                        area(*a.1).total_cmp(&area(*b.1))
                    })
                    .map(|(slot, _)| slot);
                let Some(slot) = open else { break };
                let k = kids.swap_remove(slot);
                let c = b2.nodes[k].first_index as usize;
                kids.extend([c, c + 1]);
            }
            for (slot, &k) in kids.iter().enumerate() {
                let node = &b2.nodes[k];
                let child = if packs(k) {
                    this.leaf(&b2, k, tris)
                } else {
                    this.nodes.push(Node::empty());
                    work.push((k, this.nodes.len() - 1));
                    (this.nodes.len() - 1) as u32
                };
                this.nodes[at].set(slot, node.aabb().min, node.aabb().max, child);
            }
        }
        // A path pushes at most three siblings per level of inner nodes.
        this.deep = 3 * this.depth() + 1 > STACK;
        this
    }

    /// Packs the triangles under binary node `b` into packets: one when they fit, else a
    /// node of up to four leaves (a binary leaf holds one triangle with the build's
    /// settings, so this is a safeguard), each with `b`'s box.
    fn leaf(&mut self, b2: &obvhs::bvh2::Bvh2, b: usize, tris: &[Triangle]) -> u32 {
        let mut prims = Vec::new();
        let mut todo = vec![b];
        while let Some(i) = todo.pop() {
            let node = &b2.nodes[i];
            if node.is_leaf() {
                let s = node.first_index as usize;
                prims.extend_from_slice(&b2.primitive_indices[s..s + node.prim_count as usize]);
            } else {
                todo.extend([node.first_index as usize + 1, node.first_index as usize]);
            }
        }
        self.pack(&prims, b2.nodes[b].aabb().min, b2.nodes[b].aabb().max, tris)
    }

    fn pack(&mut self, prims: &[u32], lo: Vec3A, hi: Vec3A, tris: &[Triangle]) -> u32 {
        if prims.len() <= LEAF_MAX as usize {
            let mut p = Packet {
                v0: [Vec4::ZERO; 3],
                e1: [Vec4::ZERO; 3],
                e2: [Vec4::ZERO; 3],
                id: [EMPTY; 4],
            };
            for (lane, &prim) in prims.iter().enumerate() {
                let t = &tris[prim as usize];
                let (e1, e2) = (t.v1 - t.v0, t.v2 - t.v0);
                for a in 0..3 {
                    p.v0[a][lane] = t.v0[a];
                    p.e1[a][lane] = e1[a];
                    p.e2[a][lane] = e2[a];
                }
                p.id[lane] = prim;
            }
            self.packets.push(p);
            return LEAF_BIT | (self.packets.len() - 1) as u32;
        }
        let at = self.nodes.len();
        self.nodes.push(Node::empty());
        let chunk = prims.len().div_ceil(4);
        for (slot, part) in prims.chunks(chunk).enumerate() {
            let child = self.pack(part, lo, hi, tris);
            self.nodes[at].set(slot, lo, hi, child);
        }
        at as u32
    }

    /// The closest hit along `ray` that `keep(id, u, v)` accepts (an any-hit filter: alpha
    /// masks); among equally near hits the lowest id, whatever the tree's layout (a
    /// rasteriser's depth test keeps the first triangle drawn the same way).
    pub(crate) fn closest(
        &self,
        ray: &PreparedRay,
        keep: impl Fn(u32, f32, f32) -> bool,
    ) -> Option<Found> {
        if self.deep {
            self.closest_with(ray, &keep, Vec::new())
        } else {
            self.closest_with(ray, &keep, ArrayStack::new())
        }
    }

    /// True when `ray` meets a triangle that `keep` accepts.
    pub(crate) fn any(&self, ray: &PreparedRay, keep: impl Fn(u32, f32, f32) -> bool) -> bool {
        if self.deep {
            self.any_with(ray, &keep, Vec::new())
        } else {
            self.any_with(ray, &keep, ArrayStack::new())
        }
    }

    #[inline(always)]
    fn closest_with(
        &self,
        ray: &PreparedRay,
        keep: &impl Fn(u32, f32, f32) -> bool,
        mut stack: impl Stack,
    ) -> Option<Found> {
        let mut best: Option<Found> = None;
        let mut t_max = ray.t_max;
        let mut current = 0u32;
        loop {
            if current & LEAF_BIT == 0 {
                let node = &self.nodes[current as usize];
                let (mask, near) = ray.boxes(node, t_max);
                match mask.count_ones() {
                    0 => {}
                    1 => {
                        current = node.child[mask.trailing_zeros() as usize];
                        continue;
                    }
                    _ => {
                        // Sort the hit children by entry distance, push all but the
                        // nearest (farthest first), and descend into the nearest.
                        let near = near.to_array();
                        let mut hit = [(0u32, 0f32); 4];
                        let mut k = 0;
                        let mut m = mask;
                        while m != 0 {
                            let lane = m.trailing_zeros() as usize;
                            m &= m - 1;
                            let mut j = k;
                            while j > 0 && hit[j - 1].1 < near[lane] {
                                hit[j] = hit[j - 1];
                                j -= 1;
                            }
                            hit[j] = (node.child[lane], near[lane]);
                            k += 1;
                        }
                        for &(c, t) in &hit[..k - 1] {
                            stack.push(c, t);
                        }
                        current = hit[k - 1].0;
                        continue;
                    }
                }
            } else {
                let p = &self.packets[(current & !LEAF_BIT) as usize];
                let (valid, t, u, v) = ray.triangles(p, t_max);
                let mut m = valid.bitmask();
                if m != 0 {
                    let (t, u, v) = (t.to_array(), u.to_array(), v.to_array());
                    while m != 0 {
                        // The nearest remaining lane (the lowest id on ties).
                        let before =
                            |t0: f32, i0: u32, t1: f32, i1: u32| t0 < t1 || (t0 == t1 && i0 < i1);
                        let mut lane = m.trailing_zeros() as usize;
                        let mut rest = m & (m - 1);
                        while rest != 0 {
                            let l = rest.trailing_zeros() as usize;
                            rest &= rest - 1;
                            if before(t[l], p.id[l], t[lane], p.id[lane]) {
                                lane = l;
                            }
                        }
                        m &= !(1 << lane);
                        let nearer = best.is_none_or(|b| before(t[lane], p.id[lane], b.t, b.id));
                        if nearer && keep(p.id[lane], u[lane], v[lane]) {
                            best = Some(Found {
                                id: p.id[lane],
                                t: t[lane],
                                u: u[lane],
                                v: v[lane],
                            });
                            t_max = t[lane];
                            break;
                        }
                    }
                }
            }
            // Next: the nearest pushed child the ray may still reach.
            loop {
                match stack.pop() {
                    None => return best,
                    Some((c, t)) if t <= t_max => {
                        current = c;
                        break;
                    }
                    Some(_) => {}
                }
            }
        }
    }

    #[inline(always)]
    fn any_with(
        &self,
        ray: &PreparedRay,
        keep: &impl Fn(u32, f32, f32) -> bool,
        mut stack: impl Stack,
    ) -> bool {
        let mut current = 0u32;
        loop {
            if current & LEAF_BIT == 0 {
                let node = &self.nodes[current as usize];
                let (mut mask, _) = ray.boxes(node, ray.t_max);
                if mask != 0 {
                    current = node.child[mask.trailing_zeros() as usize];
                    mask &= mask - 1;
                    while mask != 0 {
                        stack.push(node.child[mask.trailing_zeros() as usize], 0.0);
                        mask &= mask - 1;
                    }
                    continue;
                }
            } else {
                let p = &self.packets[(current & !LEAF_BIT) as usize];
                let (valid, _, u, v) = ray.triangles(p, ray.t_max);
                let mut m = valid.bitmask();
                if m != 0 {
                    let (u, v) = (u.to_array(), v.to_array());
                    while m != 0 {
                        let lane = m.trailing_zeros() as usize;
                        m &= m - 1;
                        if keep(p.id[lane], u[lane], v[lane]) {
                            return true;
                        }
                    }
                }
            }
            match stack.pop() {
                Some((c, _)) => current = c,
                None => return false,
            }
        }
    }

    /// The box of every triangle (the root's children's boxes together); an empty box
    /// (lower corner above the upper) for a tree without triangles.
    pub(crate) fn bounds(&self) -> (Vec3A, Vec3A) {
        let root = &self.nodes[0];
        let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
        for slot in (0..4).filter(|s| root.used & (1 << s) != 0) {
            lo = lo.min(Vec3A::new(
                root.lo[0][slot],
                root.lo[1][slot],
                root.lo[2][slot],
            ));
            hi = hi.max(Vec3A::new(
                root.hi[0][slot],
                root.hi[1][slot],
                root.hi[2][slot],
            ));
        }
        (lo, hi)
    }

    /// Inner nodes on the longest path from the root.
    fn depth(&self) -> usize {
        let mut deepest = 0;
        let mut todo = vec![(0u32, 1usize)];
        while let Some((n, d)) = todo.pop() {
            deepest = deepest.max(d);
            for &c in &self.nodes[n as usize].child {
                if c != EMPTY && c & LEAF_BIT == 0 {
                    todo.push((c, d + 1));
                }
            }
        }
        deepest
    }

    /// The tree as the GPU path tracer reads it (`Node` and `Packet` of
    /// `shaders/scene-core/path_tracer.wgsl`): each node as 32 four-byte words (the six
    /// box rows, the children, the used mask, padding), each packet as 40 (nine rows of
    /// lanes, the ids), integers as their bits; and whether a traversal may need more than
    /// the shader's stack of [`STACK`] entries (the same bound as the CPU's fixed stack).
    #[cfg(all(feature = "gpu", feature = "reference"))]
    pub(crate) fn gpu_words(&self) -> (Vec<[u32; 32]>, Vec<[u32; 40]>, bool) {
        let row = |v: &Vec4| v.to_array().map(f32::to_bits);
        let nodes = self
            .nodes
            .iter()
            .map(|n| {
                let mut w = [0u32; 32];
                for (r, v) in n.lo.iter().chain(&n.hi).enumerate() {
                    w[4 * r..4 * r + 4].copy_from_slice(&row(v));
                }
                w[24..28].copy_from_slice(&n.child);
                w[28] = n.used;
                w
            })
            .collect();
        let packets = self
            .packets
            .iter()
            .map(|p| {
                let mut w = [0u32; 40];
                for (r, v) in p.v0.iter().chain(&p.e1).chain(&p.e2).enumerate() {
                    w[4 * r..4 * r + 4].copy_from_slice(&row(v));
                }
                w[36..40].copy_from_slice(&p.id);
                w
            })
            .collect();
        (nodes, packets, self.deep)
    }

    /// Heap bytes of the tree.
    pub(crate) fn bytes(&self) -> usize {
        self.nodes.len() * size_of::<Node>() + self.packets.len() * size_of::<Packet>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{Rng, uniform_sphere};

    fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Triangle {
        Triangle {
            v0: Vec3A::from(a),
            v1: Vec3A::from(b),
            v2: Vec3A::from(c),
        }
    }

    /// The nearest hit over all triangles (the lowest index on ties), and whether any hits.
    fn brute(tris: &[Triangle], ray: (Vec3A, Vec3A, f32, f32)) -> (Option<(u32, f32)>, bool) {
        let (o, d, t0, t1) = ray;
        let mut best: Option<(u32, f32)> = None;
        for (i, t) in tris.iter().enumerate() {
            if let Some((th, _, _)) = intersect_one(t.v0, t.v1 - t.v0, t.v2 - t.v0, o, d, t0, t1)
                && best.is_none_or(|b| th < b.1)
            {
                best = Some((i as u32, th));
            }
        }
        (best, best.is_some())
    }

    fn check(bvh: &Bvh4, tris: &[Triangle], rays: &[(Vec3A, Vec3A, f32, f32)]) -> usize {
        let mut hits = 0;
        for &(o, d, t0, t1) in rays {
            let prepared = PreparedRay::new(o, d, t0, t1);
            let found = bvh.closest(&prepared, |_, _, _| true);
            let (want, any) = brute(tris, (o, d, t0, t1));
            match (found, want) {
                (Some(f), Some((id, t))) => {
                    hits += 1;
                    // The same distance (identical arithmetic); the triangle may differ only
                    // where two are equally near.
                    assert_eq!(f.t, t, "ray {o} {d}");
                    if f.id != id {
                        let e = &tris[f.id as usize];
                        let again = intersect_one(e.v0, e.v1 - e.v0, e.v2 - e.v0, o, d, t0, t1);
                        assert_eq!(again.map(|h| h.0), Some(t));
                    }
                }
                (None, None) => {}
                _ => panic!("ray {o} {d} [{t0}, {t1}]: tree {found:?}, brute force {want:?}"),
            }
            assert_eq!(bvh.any(&prepared, |_, _, _| true), any, "ray {o} {d}");
        }
        hits
    }

    /// A box field of axis-aligned quads with rays along the axes, in the coordinate planes
    /// and from origins on the boxes' planes: the zero direction components and touching
    /// slabs that a slab test must not get wrong.
    #[test]
    fn axis_aligned_rays_on_box_planes_match_brute_force() {
        let mut tris = Vec::new();
        for i in 0..6 {
            for j in 0..6 {
                let (x, z) = (i as f32 * 2.0, j as f32 * 2.0);
                let y = ((i * 7 + j * 3) % 5) as f32;
                tris.push(tri([x, y, z], [x + 1.0, y, z], [x + 1.0, y, z + 1.0]));
                tris.push(tri([x, y, z], [x + 1.0, y, z + 1.0], [x, y, z + 1.0]));
                tris.push(tri([x, 0.0, z], [x, y + 1.0, z], [x, y + 1.0, z + 1.0]));
            }
        }
        let bvh = Bvh4::build(&tris, BvhBuildParams::very_slow_build());
        let mut rays = Vec::new();
        let dirs = [
            Vec3A::X,
            Vec3A::NEG_X,
            Vec3A::Y,
            Vec3A::NEG_Y,
            Vec3A::Z,
            Vec3A::NEG_Z,
            Vec3A::new(1.0, -1.0, 0.0).normalize(),
            Vec3A::new(0.0, -1.0, -1.0).normalize(),
            Vec3A::new(-1.0, 0.0, 1.0).normalize(),
            Vec3A::new(-0.0, -1.0, 0.0),
        ];
        for a in 0..13 {
            for b in 0..13 {
                for c in 0..6 {
                    let o = Vec3A::new(a as f32 * 0.5 - 0.5, c as f32, b as f32 * 0.5 - 0.5);
                    for d in dirs {
                        rays.push((o, d, 0.0, f32::INFINITY));
                        rays.push((o, d, 0.25, 2.5));
                    }
                }
            }
        }
        let hits = check(&bvh, &tris, &rays);
        assert!(hits > rays.len() / 10, "{hits} hits of {}", rays.len());
    }

    /// Random soups with random ranges; then the same tree with the growable stack.
    #[test]
    fn random_soups_match_brute_force_with_either_stack() {
        for seed in 0..4u64 {
            let mut rng = Rng::new(seed, 5);
            let tris: Vec<Triangle> = (0..1500)
                .map(|_| {
                    let c = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
                    let p = [0, 1, 2]
                        .map(|_| c + Vec3A::from(uniform_sphere(rng.next_vec2())) * rng.next_f32());
                    Triangle {
                        v0: p[0],
                        v1: p[1],
                        v2: p[2],
                    }
                })
                .collect();
            let mut bvh = Bvh4::build(&tris, BvhBuildParams::medium_build());
            let rays: Vec<_> = (0..1500)
                .map(|_| {
                    let o = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 12.0;
                    let d = Vec3A::from(uniform_sphere(rng.next_vec2()));
                    let t0 = rng.next_f32() * 2.0;
                    (o, d, t0, t0 + rng.next_f32() * 8.0)
                })
                .collect();
            let hits = check(&bvh, &tris, &rays);
            assert!(hits > 100, "{hits}");
            assert!(!bvh.deep);
            bvh.deep = true;
            assert_eq!(check(&bvh, &tris, &rays), hits);
        }
    }

    /// An any-hit filter that rejects a lane makes the closest hit the next one behind it.
    #[test]
    fn a_rejected_hit_lets_the_one_behind_through() {
        let tris: Vec<Triangle> = (0..6)
            .map(|k| {
                let z = k as f32;
                tri([-1.0, -1.0, z], [1.0, -1.0, z], [0.0, 1.0, z])
            })
            .collect();
        let bvh = Bvh4::build(&tris, BvhBuildParams::very_slow_build());
        let ray = PreparedRay::new(Vec3A::new(0.0, 0.0, -1.0), Vec3A::Z, 0.0, f32::INFINITY);
        let found = bvh.closest(&ray, |id, _, _| id != 0 && id != 1).unwrap();
        assert_eq!((found.id, found.t), (2, 3.0));
        assert!(!bvh.any(&ray, |_, _, _| false));
        assert!(bvh.any(&ray, |id, _, _| id == 5));
    }

    /// The range is half-open, `[t_min, t_max)`, as obvhs' traversal had it: a segment that
    /// ends exactly on a surface is not blocked by it (relighting's display welds element
    /// corners by such segments along walls), and one that starts on it is.
    #[test]
    fn a_hit_exactly_at_t_max_does_not_count() {
        let tris = vec![tri([-1.0, -1.0, 2.0], [1.0, -1.0, 2.0], [0.0, 1.0, 2.0])];
        let bvh = Bvh4::build(&tris, BvhBuildParams::very_slow_build());
        let at = |t0: f32, t1: f32| PreparedRay::new(Vec3A::ZERO, Vec3A::Z, t0, t1);
        assert!(!bvh.any(&at(0.0, 2.0), |_, _, _| true));
        assert!(bvh.closest(&at(0.0, 2.0), |_, _, _| true).is_none());
        assert!(bvh.any(&at(2.0, 3.0), |_, _, _| true));
        assert_eq!(
            bvh.closest(&at(0.0, 2.5), |_, _, _| true).map(|f| f.t),
            Some(2.0)
        );
    }
}
