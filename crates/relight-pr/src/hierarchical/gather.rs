//! The links of the hierarchical solve and their gather: far, near and cluster links
//! sorted by receiver, and one Jacobi step over them (pull up the tree, gather, push down,
//! read at the leaves).

use glam::Vec3;
use rayon::prelude::*;

use super::tree::{NONE, Tree};
use super::{CLUSTER_LINK_BYTES, FAR_LINK_BYTES, Links, NEAR_LINK_BYTES};
use crate::mesh::Meshing;

/// A link between two nodes treated as points: the receiver gets
/// `w (-w . P_sender) g` (vector irradiance), `g = V / (pi d^2)`.
#[derive(Clone, Copy, Debug)]
pub(super) struct FarLink {
    pub(super) receiver: u32,
    pub(super) sender: u32,
    pub(super) w: Vec3,
    pub(super) g: f32,
}

/// A link from an element: the receiver's irradiance gains `f B_sender`. The receiver is an
/// element for a near link, and a node for a sample of a cluster link whose sender's
/// elements send their own radiosity ([`Refiner::cluster`] between the element budget's
/// groups: every leaf of the node gains it).
#[derive(Clone, Copy, Debug)]
pub(super) struct NearLink {
    pub(super) receiver: u32,
    pub(super) sender: u32,
    pub(super) f: f32,
}

/// A link between two clusters at the element budget: every leaf of the receiver gains
/// irradiance `c Phi_sender`, `Phi` the sender's power `sum B A` ([`Refiner::cluster`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct ClusterLink {
    pub(super) receiver: u32,
    pub(super) sender: u32,
    pub(super) c: f32,
}

/// Offsets of a receiver-sorted link list: `offsets[i]..offsets[i + 1]` are receiver
/// `i`'s links.
pub(super) fn offsets(receivers: impl Iterator<Item = u32>, count: usize) -> Vec<u32> {
    let mut offsets = vec![0u32; count + 1];
    for r in receivers {
        offsets[r as usize + 1] += 1;
    }
    for i in 0..count {
        offsets[i + 1] += offsets[i];
    }
    offsets
}

/// One link set ready to gather.
pub(super) struct LinkSet {
    pub(super) far: Vec<FarLink>,
    pub(super) far_offsets: Vec<u32>,
    pub(super) near: Vec<NearLink>,
    pub(super) near_offsets: Vec<u32>,
    pub(super) cluster: Vec<ClusterLink>,
    pub(super) cluster_offsets: Vec<u32>,
    /// Cluster links' samples from elements to nodes.
    pub(super) sampled: Vec<NearLink>,
    pub(super) sampled_offsets: Vec<u32>,
    /// Cluster links made of samples: distinct (receiver node, sender node) pairs are not
    /// kept, this counts them as made.
    pub(super) sampled_links: usize,
}

impl LinkSet {
    pub(super) fn new(links: Links, nodes: usize, elements: usize) -> Self {
        let far_offsets = offsets(links.far.iter().map(|l| l.receiver), nodes);
        let near_offsets = offsets(links.near.iter().map(|l| l.receiver), elements);
        let cluster_offsets = offsets(links.cluster.iter().map(|l| l.receiver), nodes);
        let sampled_offsets = offsets(links.sampled.iter().map(|l| l.receiver), nodes);
        Self {
            sampled: links.sampled,
            sampled_offsets,
            sampled_links: links.sampled_links,
            far: links.far,
            far_offsets,
            near: links.near,
            near_offsets,
            cluster: links.cluster,
            cluster_offsets,
        }
    }

    pub(super) fn bytes(&self) -> usize {
        self.far.len() * FAR_LINK_BYTES
            + self.near.len() * NEAR_LINK_BYTES
            + self.cluster.len() * CLUSTER_LINK_BYTES
            + self.sampled.len() * NEAR_LINK_BYTES
            + (self.far_offsets.len()
                + self.near_offsets.len()
                + self.cluster_offsets.len()
                + self.sampled_offsets.len())
                * 4
    }
}

/// The nodes a gather runs over ("slots"): the cluster tree's nodes at which a link
/// ends, their ancestors, and below them nothing ([`GatherTree::compact`]). A node's
/// subtree where no link ends only passes its irradiance down to its leaves and sums
/// their power up: it is one bucket. Where the element budget groups the elements, no
/// reflected-light link ends inside a group (the Breakfast Room's 719 511 nodes, two
/// sources, held 138 MB; the groups and above are 9 219); without groups, links reach
/// few leaves (most leaf pairs are near links, which run element to element): the
/// building's 191 019 nodes held 238 MB for its 13 sources.
pub(super) struct GatherTree {
    /// Per slot (pre-order: children after parents), its children's slots, or
    /// [`NONE`] for a bucket: a slot whose leaves send and receive through it directly.
    pub(super) children: Vec<[u32; 2]>,
    /// Per slot, its leaves in leaf order (`first`, `count`).
    pub(super) leaves: Vec<[u32; 2]>,
    /// Per element, its bucket ([`NONE`] for hidden elements).
    pub(super) bucket_of: Vec<u32>,
}

impl GatherTree {
    /// The slots for `links` over `tree` (the root always one), and `links` renumbered
    /// as slots (elements stay). The slots keep the nodes' order, and so the links'
    /// sorting.
    pub(super) fn compact(tree: &Tree, mut links: Links) -> (Self, Links) {
        let nodes = &tree.nodes;
        let mut ends = vec![false; nodes.len()];
        node_ends(&mut links, |i| ends[*i as usize] = true);
        // Whether a link ends strictly below each node (post-order: children first).
        let mut below = vec![false; nodes.len()];
        for (i, node) in nodes.iter().enumerate().rev() {
            if !node.leaf() {
                below[i] = node
                    .children
                    .iter()
                    .any(|&c| ends[c as usize] || below[c as usize]);
            }
        }
        // Kept: the root and the children of every kept node a link ends below.
        let mut keep = vec![false; nodes.len()];
        if !nodes.is_empty() {
            keep[0] = true;
        }
        for (i, node) in nodes.iter().enumerate() {
            if keep[i] && below[i] {
                for c in node.children {
                    keep[c as usize] = true;
                }
            }
        }
        drop(ends);
        let mut slot_of = vec![NONE; nodes.len()];
        let mut count = 0u32;
        for (i, &k) in keep.iter().enumerate() {
            if k {
                slot_of[i] = count;
                count += 1;
            }
        }
        let mut children = Vec::with_capacity(count as usize);
        let mut leaves = Vec::with_capacity(count as usize);
        let mut bucket_of = vec![NONE; tree.leaf_of.len()];
        for (i, node) in nodes.iter().enumerate() {
            if !keep[i] {
                continue;
            }
            leaves.push([node.first, node.count]);
            if below[i] {
                children.push(node.children.map(|c| slot_of[c as usize]));
            } else {
                children.push([NONE; 2]);
                for p in node.first..node.first + node.count {
                    bucket_of[tree.order[p as usize] as usize] = slot_of[i];
                }
            }
        }
        node_ends(&mut links, |i| *i = slot_of[*i as usize]);
        (
            Self {
                children,
                leaves,
                bucket_of,
            },
            links,
        )
    }

    /// Number of slots.
    pub(super) fn len(&self) -> usize {
        self.children.len()
    }
}

/// Scratch of the gather: per node and source, the vector a node sends (`sum B A n`, RGB per
/// axis) and the vector irradiance it receives.
pub(super) struct Gather {
    pub(super) k: usize,
    pub(super) sent: Vec<[Vec3; 3]>,
    pub(super) received: Vec<[Vec3; 3]>,
    /// Per node and source, the power it sends (`sum B A`, RGB) and the mean irradiance its
    /// cluster links bring it.
    pub(super) power: Vec<Vec3>,
    pub(super) mean: Vec<Vec3>,
    /// Per node, bit `m` of word `m / 64`: whether it sends anything of source `m`
    /// (a source lights a few rooms of a building; the gather skips the rest).
    pub(super) active: Vec<u64>,
}

impl Gather {
    pub(super) fn new(nodes: usize, k: usize) -> Self {
        Self {
            k,
            sent: vec![[Vec3::ZERO; 3]; nodes * k],
            received: vec![[Vec3::ZERO; 3]; nodes * k],
            power: vec![Vec3::ZERO; nodes * k],
            mean: vec![Vec3::ZERO; nodes * k],
            active: vec![0; nodes * k.div_ceil(64)],
        }
    }
}

impl Gather {
    /// The irradiance every element receives over `links` from radiosity `b`
    /// (element-major `j * k + m`), into `out` (same layout; hidden elements zero).
    pub(super) fn run(
        &mut self,
        (slots, tree): (&GatherTree, &Tree),
        meshing: &Meshing,
        links: &LinkSet,
        b: &[Vec3],
        out: &mut [Vec3],
    ) {
        let k = self.k;
        let els = &meshing.elements;
        // Pull: buckets from their leaves' radiosity, parents as the sum of their children
        // (pre-order: children after parents).
        self.sent
            .par_chunks_mut(k)
            .zip(self.power.par_chunks_mut(k))
            .zip(slots.children.par_iter().zip(slots.leaves.par_iter()))
            .for_each(|((sent, power), (children, &[first, count]))| {
                if children[0] == NONE {
                    sent.fill([Vec3::ZERO; 3]);
                    power.fill(Vec3::ZERO);
                    for p in first..first + count {
                        let j = tree.order[p as usize] as usize;
                        let (a, n) = (els[j].area, els[j].normal);
                        for m in 0..k {
                            let w = b[j * k + m] * a;
                            let s = &mut sent[m];
                            s[0] += w * n.x;
                            s[1] += w * n.y;
                            s[2] += w * n.z;
                            power[m] += w;
                        }
                    }
                }
            });
        let words = k.div_ceil(64);
        for i in (0..slots.len()).rev() {
            let [l, r] = slots.children[i];
            if l != NONE {
                for m in 0..k {
                    let (a, c) = (self.sent[l as usize * k + m], self.sent[r as usize * k + m]);
                    self.sent[i * k + m] = [a[0] + c[0], a[1] + c[1], a[2] + c[2]];
                    self.power[i * k + m] =
                        self.power[l as usize * k + m] + self.power[r as usize * k + m];
                }
                for w in 0..words {
                    self.active[i * words + w] =
                        self.active[l as usize * words + w] | self.active[r as usize * words + w];
                }
            } else {
                for w in 0..words {
                    let mut bits = 0u64;
                    for m in w * 64..(w * 64 + 64).min(k) {
                        if self.sent[i * k + m] != [Vec3::ZERO; 3] {
                            bits |= 1 << (m - w * 64);
                        }
                    }
                    self.active[i * words + w] = bits;
                }
            }
        }
        // Gather over the far and cluster links, receiver by receiver.
        let sent = &self.sent;
        let power = &self.power;
        let active = &self.active;
        self.received
            .par_chunks_mut(k)
            .zip(self.mean.par_chunks_mut(k))
            .enumerate()
            .for_each(|(i, (recv, mean))| {
                recv.fill([Vec3::ZERO; 3]);
                mean.fill(Vec3::ZERO);
                let (a, z) = (
                    links.cluster_offsets[i] as usize,
                    links.cluster_offsets[i + 1] as usize,
                );
                for l in &links.cluster[a..z] {
                    let s = l.sender as usize;
                    each_active(&active[s * words..(s + 1) * words], |m| {
                        mean[m] += power[s * k + m] * l.c;
                    });
                }
                from_elements(mean, &links.sampled, &links.sampled_offsets, i, b);
                let (a, z) = (
                    links.far_offsets[i] as usize,
                    links.far_offsets[i + 1] as usize,
                );
                for l in &links.far[a..z] {
                    let w = l.w;
                    let s = l.sender as usize;
                    each_active(&active[s * words..(s + 1) * words], |m| {
                        let p = &sent[s * k + m];
                        let out = -(p[0] * w.x + p[1] * w.y + p[2] * w.z) * l.g;
                        recv[m][0] += out * w.x;
                        recv[m][1] += out * w.y;
                        recv[m][2] += out * w.z;
                    });
                }
            });
        // Push down to the buckets.
        for (i, &[l, r]) in slots.children.iter().enumerate() {
            if l != NONE {
                for m in 0..k {
                    let v = self.received[i * k + m];
                    let e = self.mean[i * k + m];
                    for c in [l, r] {
                        let d = &mut self.received[c as usize * k + m];
                        d[0] += v[0];
                        d[1] += v[1];
                        d[2] += v[2];
                        self.mean[c as usize * k + m] += e;
                    }
                }
            }
        }
        // Leaves read their irradiance, plus their cluster links' and near links'.
        let received = &self.received;
        let mean = &self.mean;
        out.par_chunks_mut(k).enumerate().for_each(|(j, e)| {
            let leaf = slots.bucket_of[j];
            if leaf == NONE {
                e.fill(Vec3::ZERO);
                return;
            }
            let n = els[j].normal;
            for m in 0..k {
                let v = received[leaf as usize * k + m];
                e[m] = (v[0] * n.x + v[1] * n.y + v[2] * n.z).max(Vec3::ZERO)
                    + mean[leaf as usize * k + m];
            }
            from_elements(e, &links.near, &links.near_offsets, j, b);
        });
    }
}

/// Adds to `out` (receiver `i`'s irradiance per source) what its links from elements
/// (`links[offsets[i]..offsets[i + 1]]`) bring from radiosity `b` (element-major).
fn from_elements(out: &mut [Vec3], links: &[NearLink], offsets: &[u32], i: usize, b: &[Vec3]) {
    let k = out.len();
    for l in &links[offsets[i] as usize..offsets[i + 1] as usize] {
        for (m, o) in out.iter_mut().enumerate() {
            *o += b[l.sender as usize * k + m] * l.f;
        }
    }
}

/// Calls `f` with each source whose bit is set in `words` (bit `m` of word `m / 64`).
fn each_active(words: &[u64], mut f: impl FnMut(usize)) {
    for (word, &w) in words.iter().enumerate() {
        let mut bits = w;
        while bits != 0 {
            f(word * 64 + bits.trailing_zeros() as usize);
            bits &= bits - 1;
        }
    }
}

/// Calls `f` on every node a link of `links` ends at: far and cluster links' receivers
/// and senders, sampled links' receivers (their senders, as near links' ends, are
/// elements).
fn node_ends(links: &mut Links, mut f: impl FnMut(&mut u32)) {
    for l in &mut links.far {
        f(&mut l.receiver);
        f(&mut l.sender);
    }
    for l in &mut links.cluster {
        f(&mut l.receiver);
        f(&mut l.sender);
    }
    for l in &mut links.sampled {
        f(&mut l.receiver);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshSettings;
    use scene_core::ray::RayScene;
    use scene_core::sampling::Rng;

    /// The gather over the compact slots ([`GatherTree::compact`]) equals a brute-force sum
    /// over every link and every element under its receiver, for links that end anywhere
    /// in the tree (far, cluster and sampled links at random nodes, near links at random
    /// elements) and two sources, one of them dark on half the elements.
    #[test]
    fn compact_gather_equals_the_sum_over_links() {
        let scene = scene_core::builtin::scene("corridor").unwrap();
        let meshing = Meshing::new(&scene, &MeshSettings::elements(256), 1).unwrap();
        let rays = RayScene::build(&scene);
        let tree = Tree::build(&meshing, &rays, false);
        let (n, nodes, k) = (meshing.elements.len(), tree.nodes.len() as u32, 2);
        let mut rng = Rng::new(7, 0);
        let mut pick = |count: u32| ((rng.next_f32() * count as f32) as u32).min(count - 1);
        let mut links = Links::default();
        for _ in 0..300 {
            let (receiver, sender) = (pick(nodes), pick(nodes));
            let w = Vec3::new(
                pick(1000) as f32 - 500.0,
                pick(1000) as f32 - 500.0,
                pick(1000) as f32 - 500.0,
            )
            .normalize_or(Vec3::X);
            links.far.push(FarLink {
                receiver,
                sender,
                w,
                g: 1e-3 * (1 + pick(100)) as f32,
            });
            let (receiver, sender) = (pick(nodes), pick(nodes));
            let c = 1e-4 * (1 + pick(100)) as f32;
            links.cluster.push(ClusterLink {
                receiver,
                sender,
                c,
            });
            let (receiver, sender) = (pick(nodes), pick(n as u32));
            let f = 1e-3 * (1 + pick(100)) as f32;
            links.sampled.push(NearLink {
                receiver,
                sender,
                f,
            });
            let (receiver, sender) = (pick(n as u32), pick(n as u32));
            let f = 1e-3 * (1 + pick(100)) as f32;
            links.near.push(NearLink {
                receiver,
                sender,
                f,
            });
        }
        links.far.sort_by_key(|l| (l.receiver, l.sender));
        links.cluster.sort_by_key(|l| (l.receiver, l.sender));
        links.sampled.sort_by_key(|l| (l.receiver, l.sender));
        links.near.sort_by_key(|l| (l.receiver, l.sender));
        let b: Vec<Vec3> = (0..n * k)
            .map(|i| {
                let (j, m) = (i / k, i % k);
                if m == 1 && j % 2 == 0 {
                    Vec3::ZERO
                } else {
                    Vec3::new(1.0, 0.5, 0.25) * (1 + (j * 7 + m) % 5) as f32
                }
            })
            .collect();
        // Brute force: each element's irradiance from the links whose receiver holds it.
        let els = &meshing.elements;
        let mut position = vec![u32::MAX; n];
        for (p, &j) in tree.order.iter().enumerate() {
            position[j as usize] = p as u32;
        }
        let under = |node: u32| {
            let node = &tree.nodes[node as usize];
            tree.order[node.first as usize..(node.first + node.count) as usize]
                .iter()
                .map(|&j| j as usize)
        };
        let holds = |node: u32, j: usize| {
            let node = &tree.nodes[node as usize];
            (node.first..node.first + node.count).contains(&position[j])
        };
        let mut expected = vec![Vec3::ZERO; n * k];
        for j in 0..n {
            if position[j] == u32::MAX {
                continue;
            }
            for m in 0..k {
                let mut vector = [Vec3::ZERO; 3];
                let mut scalar = Vec3::ZERO;
                for l in links.far.iter().filter(|l| holds(l.receiver, j)) {
                    let mut p = [Vec3::ZERO; 3];
                    for s in under(l.sender) {
                        let w = b[s * k + m] * els[s].area;
                        p[0] += w * els[s].normal.x;
                        p[1] += w * els[s].normal.y;
                        p[2] += w * els[s].normal.z;
                    }
                    let out = -(p[0] * l.w.x + p[1] * l.w.y + p[2] * l.w.z) * l.g;
                    vector[0] += out * l.w.x;
                    vector[1] += out * l.w.y;
                    vector[2] += out * l.w.z;
                }
                for l in links.cluster.iter().filter(|l| holds(l.receiver, j)) {
                    let power: Vec3 = under(l.sender).map(|s| b[s * k + m] * els[s].area).sum();
                    scalar += power * l.c;
                }
                for l in links.sampled.iter().filter(|l| holds(l.receiver, j)) {
                    scalar += b[l.sender as usize * k + m] * l.f;
                }
                for l in links.near.iter().filter(|l| l.receiver as usize == j) {
                    scalar += b[l.sender as usize * k + m] * l.f;
                }
                let nrm = els[j].normal;
                expected[j * k + m] = (vector[0] * nrm.x + vector[1] * nrm.y + vector[2] * nrm.z)
                    .max(Vec3::ZERO)
                    + scalar;
            }
        }
        let (slots, links) = GatherTree::compact(&tree, links);
        assert!(slots.len() < tree.nodes.len(), "{} slots", slots.len());
        let links = LinkSet::new(links, slots.len(), n);
        let mut out = vec![Vec3::splat(f32::NAN); n * k];
        Gather::new(slots.len(), k).run((&slots, &tree), &meshing, &links, &b, &mut out);
        let scale = expected
            .iter()
            .map(|v| v.max_element())
            .fold(0.0f32, f32::max);
        assert!(scale > 0.0);
        for (i, (got, want)) in out.iter().zip(&expected).enumerate() {
            assert!(
                (*got - *want).abs().max_element() <= 1e-4 * scale,
                "element {} source {}: {got} against {want}",
                i / k,
                i % k
            );
        }
    }
}
