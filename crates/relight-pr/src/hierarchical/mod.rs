//! Hierarchical radiosity with clustering, tagged per light source: the solve that scales
//! to scenes of 10^5 elements (beyond the paper, whose progressive refinement costs one row
//! of form factors over every element per shot).
//!
//! After Hanrahan, Salzman and Aupperle (1991, hierarchical radiosity: links between
//! pieces of the scene at the level their error allows), Smits, Arvo and Greenberg (1994)
//! and Sillion (1995) (clusters: links between groups of surfaces, not only between
//! subdivisions of one). The meshing's elements are the leaves; above them a binary tree
//! of clusters, grouped first by orientation (so a cluster's surfaces face one way) and
//! then in space. A **link** from a sender node to a receiver node carries light between
//! every pair of their leaves at once:
//!
//! - far links (`(r_R + r_S) / d` below [`HierarchySettings::opening`], or a transfer too
//!   small to matter, [`HierarchySettings::link_error`]) treat both ends as points at
//!   their area-weighted centres `d` apart along the unit direction `w`. A cluster sends
//!   as the vector `P = sum_l B_l A_l n_l` of its leaves (radiosity `B`, area `A`, normal
//!   `n`) and receives the vector irradiance `w (-w . P) V / (pi d^2)`, which each leaf `l`
//!   below it reads as `n_l . (that)`: the point form factor `A cos cos / (pi d^2)`
//!   (eq. 4 of Hanrahan et al.) summed over the leaves without visiting them. This is exact
//!   in the cosines when every leaf of each end faces the other end, which the refinement
//!   guarantees (else it splits); `V` is the visible fraction of rays between random points
//!   of the two ends ([`HierarchySettings::visibility_rays`]). A partly visible link that
//!   carries enough light is split too, so that a cluster straddling a wall does not spread
//!   light onto its hidden side;
//! - near links (two elements too close for a point) use the closed-form point-to-triangle
//!   form factor at the receiver's points with ray-cast visibility
//!   ([`crate::form_factor::point_to_triangle_adaptive`]), as the progressive solve does;
//! - cluster links hold the **element budget** ([`HierarchySettings::cluster_radius`]): a
//!   cluster no wider than a target element is never split, and where two such clusters
//!   (or one and an element) cannot be linked far, every leaf of the receiver gets the
//!   mean irradiance the sender's mean radiosity gives it, estimated with closed-form
//!   form factors and rays between their leaves (Smits, Arvo and Greenberg's and Sillion's
//!   clusters seen as one element each). A file's centimetre triangles then cost what an
//!   element of the size the user asked for costs.
//!
//! Refinement is the "BF" oracle of Hanrahan et al. with an estimated radiosity: a link is
//! kept as soon as it is geometrically far enough or carries less than
//! [`HierarchySettings::link_error`] of the scene's power. Two link sets are refined: one
//! from the emitters (their emission is known), giving the direct light of emissive meshes,
//! and one for reflected light, refined against the radiosity the direct light leaves
//! (point, spot, directional lights and the sky are shot analytically onto the elements, as
//! in [`crate::solver`]). The solve is then a Jacobi iteration (gather over the links,
//! push down the tree, reflect at the leaves) per source at once, each source's energy
//! tagged as in the paper's eq. 1, each element's gathered light scaled so that its form
//! factors sum to the share of its hemisphere that surfaces cover (measured by rays), until
//! what one bounce adds falls below
//! [`HierarchySettings::tolerance`] of the first; the bounces left are added as each
//! element's last bounce times the geometric series of the bounce ratio (where the
//! progressive solve adds Cohen's uniform ambient term). The result is a [`Solution`] like the progressive solve's:
//! relighting, display, export and the GPU paths use it unchanged.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use glam::Vec3;
use rayon::prelude::*;
use scene_core::lights::LightId;
use scene_core::ray::RayScene;
use scene_core::sampling::{Rng, hash_seed};
use scene_core::{Scene, luminance};

use crate::RelightError;
use crate::form_factor::point_to_triangle_adaptive;
use crate::mesh::Meshing;
use crate::solver::{Solution, SolveStats, SolverSettings, Source};
use crate::visibility;

mod closedness;
mod gather;
mod tree;

use closedness::closedness;
use gather::{ClusterLink, FarLink, Gather, GatherTree, LinkSet, NearLink};
pub use tree::COHERENCE_RAYS;
pub(crate) use tree::budget_cut;
use tree::{Facing, Leaf, Node, Tree, facing};

/// Parameters of the hierarchical solve ([`SolverSettings::hierarchy`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HierarchySettings {
    /// A link between two nodes is far enough to treat them as points when the sum of
    /// their radii is below this fraction of their distance (Barnes and Hut's opening
    /// criterion). Smaller is more accurate and makes more links. Default 0.25.
    pub opening: f32,
    /// A link whose transfer is bounded by this fraction of the scene's (estimated) power
    /// is kept at any distance (the BF criterion of Hanrahan et al.). Default 1e-6.
    pub link_error: f64,
    /// Visibility rays per far link that carries enough light to be split where partly
    /// visible; weaker links take one ray (an unbiased estimate is all they need).
    /// Default 4.
    pub visibility_rays: u32,
    /// Visibility rays per near link (element to element), spread over the receiver's open
    /// points. Default 4.
    pub near_rays: u32,
    /// Stop when one bounce adds less than this fraction of the first bounce's power (the
    /// bounces left are added as a geometric series). Default 1e-2.
    pub tolerance: f64,
    /// Stop after this many bounces anyway. Default 500.
    pub max_bounces: usize,
    /// Most links (both sets); more is refused with [`RelightError::Budget`] while
    /// refining. Default 2^27 (3 GiB of links).
    pub max_links: usize,
    /// The element budget: a cluster whose bounding radius is at most this many radii of a
    /// target element (`sqrt(a / pi)`, `a` the meshing's target element area,
    /// [`Meshing::patch_area`] / 4) is never split. Where a link between two such nodes
    /// (or one and an element) cannot be a far link, it becomes a **cluster link**: the
    /// receiver's leaves all get the mean irradiance its area receives from the sender's
    /// mean radiosity, estimated by rays between random points of their leaves. So the
    /// centimetre triangles of a file's chairs, cups and books are solved as clusters of
    /// about an element's size (the size the user asked for), not each against each
    /// other; the elements stay for display. 0 splits down to the elements. Default 1.
    pub cluster_radius: f32,
    /// Where the element budget grouped the mesh elements ([`Meshing::groups`]) and the
    /// meshing made more than this many mesh elements per group, the reflected light is
    /// solved between the groups: the tree holds each group as one subtree, the links end
    /// at a group or above, and a cluster link keeps its samples' sender elements, so each
    /// sends its own radiosity (a group's sunlit part the sun's light, its shaded part
    /// not). The solve is then as large as the solution the user asked for, not as the
    /// file: the Breakfast Room's 278 655 mesh elements in 293 groups solve in 20 s instead
    /// of 161 s. Below the ratio the solve refines down to
    /// [`HierarchySettings::cluster_radius`] over the mesh elements and averages into the
    /// groups afterwards: slower, and closer to the progressive solve (on a cluttered room
    /// of 15 mesh elements per group the groups' solve is 2.3 % darker than it, the mesh
    /// elements' 1.1 %; on the built-in building, 24 per group, the groups' picture is 1.9
    /// points darker; docs/relight-pr.md). 0 solves between the groups wherever there are
    /// groups; infinity never. Default 32.
    pub solve_groups_above: f32,
}

impl Default for HierarchySettings {
    fn default() -> Self {
        Self {
            opening: 0.25,
            link_error: 1e-6,
            visibility_rays: 4,
            near_rays: 4,
            tolerance: 1e-2,
            max_bounces: 500,
            max_links: 1 << 27,
            cluster_radius: 1.0,
            solve_groups_above: 32.0,
        }
    }
}

impl HierarchySettings {
    /// Checks the ranges.
    pub fn check(&self) -> Result<(), RelightError> {
        let ok = self.opening > 0.0
            && self.opening <= 1.0
            && self.link_error.is_finite()
            && self.link_error >= 0.0
            && (1..=1024).contains(&self.visibility_rays)
            && (1..=1024).contains(&self.near_rays)
            && self.tolerance.is_finite()
            && self.tolerance > 0.0
            && self.max_bounces >= 1
            && self.cluster_radius.is_finite()
            && (0.0..=16.0).contains(&self.cluster_radius)
            && self.solve_groups_above >= 0.0;
        if ok {
            Ok(())
        } else {
            Err(RelightError::InvalidSetting(format!(
                "hierarchy: opening {} (in (0, 1]), link_error {} (at least 0), visibility_rays \
                 {} (1 to 1024), near_rays {} (1 to 1024), tolerance {} (above 0), max_bounces {} \
                 (at least 1), cluster_radius {} (0 to 16), solve_groups_above {} (at least 0)",
                self.opening,
                self.link_error,
                self.visibility_rays,
                self.near_rays,
                self.tolerance,
                self.max_bounces,
                self.cluster_radius,
                self.solve_groups_above
            )))
        }
    }
}

/// What a hierarchical solve built and how long each part took.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HierarchyStats {
    /// Nodes of the cluster tree (leaves are the elements that are not hidden).
    pub nodes: usize,
    /// Far links (node to node) from the emitters.
    pub direct_far_links: usize,
    /// Near links (element to element) from the emitters.
    pub direct_near_links: usize,
    /// Far links of reflected light.
    pub far_links: usize,
    /// Near links of reflected light.
    pub near_links: usize,
    /// Cluster links ([`HierarchySettings::cluster_radius`]) from the emitters.
    pub direct_cluster_links: usize,
    /// Cluster links of reflected light.
    pub cluster_links: usize,
    /// Nodes at the element budget: the coarsest nodes no larger than
    /// [`HierarchySettings::cluster_radius`] allows to split (elements included), or the
    /// groups where the solve ran between them.
    pub budget_nodes: usize,
    /// Whether the reflected light was solved between the element budget's groups
    /// ([`HierarchySettings::solve_groups_above`]).
    pub by_group: bool,
    /// Bytes of all links.
    pub link_bytes: usize,
    /// Nodes the reflected light's gather ran over: those where its links end and their
    /// ancestors (below them, a node is one bucket of its leaves).
    pub gather_nodes: usize,
    /// Bytes of the per-node, per-source vectors the gather keeps (sent and received).
    pub node_bytes: usize,
    /// Bounces iterated.
    pub bounces: usize,
    /// Building the tree.
    pub tree_time: Duration,
    /// The analytic lights' direct light on the elements.
    pub analytic_time: Duration,
    /// Refining both link sets (visibility rays and form factors).
    pub link_time: Duration,
    /// The iteration.
    pub gather_time: Duration,
}

/// Bytes of one far link.
pub const FAR_LINK_BYTES: usize = std::mem::size_of::<FarLink>();
/// Bytes of one near link.
pub const NEAR_LINK_BYTES: usize = std::mem::size_of::<NearLink>();
/// Bytes of one cluster link.
pub const CLUSTER_LINK_BYTES: usize = std::mem::size_of::<ClusterLink>();
/// Bytes per node and source of the gather's sums: the vectors sent and received (RGB per
/// axis) and the power sent and mean irradiance received (RGB).
pub const NODE_SOURCE_BYTES: usize = 2 * 3 * 12 + 2 * 12;

/// Visibility rays of a far link too weak to be split for a partial shadow (an unbiased
/// estimate of its visibility is all it needs).
const MINOR_RAYS: u32 = 1;

/// Rays that must all be blocked before a far pair that cannot be linked is dropped whole.
const CULL_RAYS: u32 = 1;

/// The opening criterion (for reflected light; half for the emitters' set) within which
/// hidden pairs are culled whole.
const CULL_OPENING: f32 = 0.25;

/// Point pairs of a cluster link, in [`HierarchySettings::visibility_rays`] (one for a
/// link too weak to be split for a partial shadow).
const CLUSTER_SAMPLES: u32 = 2;

/// The most an element's gathered light is scaled up by the normalisation.
const NORMALISE_MAX: f32 = 2.0;

/// Where a close cluster link's point is further than this many times a sender leaf's
/// reach (its corners' largest distance from its centroid) from the leaf's centroid, the
/// leaf's form factor is the point-to-point kernel at a point uniform on it, not the closed
/// form: the kernel is then at most about a tenth of the leaf's area over `pi` times its
/// reach squared.
const KERNEL_REACH: f32 = 3.0;

/// A close cluster link takes this fraction of the samples of one apart as its points.
const CLOSE_SHARE: u32 = 1;

/// Visibility rays per point of a close cluster link.
const CLOSE_RAYS: u32 = 1;

/// Points tried on a leaf for one above a cluster link's receiving point's horizon
/// (between clusters of mesh elements).
const HORIZON_TRIES: u32 = 4;

/// A partly visible far link is split when its transfer bound exceeds this multiple of the
/// [`HierarchySettings::link_error`] threshold.
const PARTIAL_SPLIT: f64 = 16.0;

/// What a term of a close cluster link's sum sends its visibility ray to: a leaf whose
/// closed form it is (a point drawn on its part above the receiving point's horizon), or
/// the point at which the kernel was taken (and its element).
#[derive(Clone, Copy)]
enum Target<'a> {
    Leaf(&'a Leaf),
    Point(Vec3, u32),
}

/// The unoccluded form factor from `x` (normal `n`, on element `own`) to leaf `b`, and
/// where its visibility ray goes; nothing from `x`'s own element (on a smooth-shaded mesh
/// its shading normal would put `x` in front of it). Where `x` is more than
/// [`KERNEL_REACH`] times the leaf's reach (its corners' largest distance from its
/// centroid) from its centroid, the point-to-point kernel at a point uniform on the leaf
/// ([`Leaf::kernel`]: unbiased, and bounded there); nearer, the closed form with the near
/// links' test of `b`'s front (a receiver in its plane sees it edge-on), exact where the
/// kernel diverges.
fn leaf_term<'l>(x: Vec3, n: Vec3, own: u32, b: &'l Leaf, rng: &mut Rng) -> (f32, Target<'l>) {
    if b.element == own || b.area <= 0.0 {
        return (0.0, Target::Leaf(b));
    }
    let centroid = (b.corners[0] + b.corners[1] + b.corners[2]) / 3.0;
    let reach2 = b
        .corners
        .iter()
        .map(|p| p.distance_squared(centroid))
        .fold(0.0f32, f32::max);
    if x.distance_squared(centroid) > KERNEL_REACH * KERNEL_REACH * reach2 {
        let (k, q) = b.kernel(x, n, rng.next_vec2());
        return (k * b.area, Target::Point(q, b.element));
    }
    let f =
        crate::form_factor::point_to_triangle(x, n, &b.corners, b.normal, None::<&RayScene>, 0, 0);
    (f, Target::Leaf(b))
}

/// What the refinement decides for a pair (receiver, sender).
enum Step {
    Drop,
    Far(FarLink),
    Near(NearLink),
    Cluster(ClusterLink),
    Sampled(Vec<NearLink>),
    Split([(u32, u32); 4], usize),
}

/// The refinement of one link set: the tree, each node's (estimated) power in the set,
/// and the limits.
struct Refiner<'a> {
    tree: &'a Tree,
    meshing: &'a Meshing,
    rays: &'a RayScene,
    power: &'a [f64],
    /// Transfers below this are kept at any distance.
    small: f64,
    settings: &'a HierarchySettings,
    /// The opening criterion of this set.
    opening: f32,
    /// Pairs whose radii sum to less than this fraction of their distance may be culled
    /// whole when hidden.
    cull_opening: f32,
    /// Nodes of this radius or less are not split ([`HierarchySettings::cluster_radius`]).
    budget_radius: f32,
    /// The groups of the element budget are the nodes not split instead
    /// ([`Tree::grouped`]; the reflected light's set when the budget grouped elements).
    whole_groups: bool,
    /// Samples of a cluster link, in [`HierarchySettings::visibility_rays`].
    cluster_samples: u32,
    full_at: f32,
    tol: f32,
    /// Distinguishes the sets' ray seeds.
    set: u64,
    links: &'a AtomicUsize,
    over: &'a AtomicBool,
}

impl Refiner<'_> {
    fn decide(&self, r: u32, s: u32) -> Step {
        let nodes = &self.tree.nodes;
        let (rn, sn) = (&nodes[r as usize], &nodes[s as usize]);
        if r == s {
            if rn.leaf() || self.power[s as usize] <= 0.0 {
                return Step::Drop;
            }
            if !self.splittable(r) {
                // Light between a budget cluster's own leaves (a chair's seat and its back).
                let count = self.cluster_samples * self.settings.visibility_rays;
                return self.cluster(r, s, count, true);
            }
            let [a, b] = rn.children;
            return Step::Split([(a, a), (a, b), (b, a), (b, b)], 4);
        }
        if self.power[s as usize] <= 0.0 {
            return Step::Drop;
        }
        let corners = |node: &Node| {
            node.leaf().then(|| {
                &self.meshing.elements[self.tree.order[node.first as usize] as usize].corners
            })
        };
        let (fr, fs) = (
            facing(rn, sn, corners(sn), self.tol),
            facing(sn, rn, corners(rn), self.tol),
        );
        if fr == Facing::Behind || fs == Facing::Behind {
            return Step::Drop;
        }
        let both_leaves = rn.leaf() && sn.leaf();
        let (split_r_ok, split_s_ok) = (self.splittable(r), self.splittable(s));
        // Whether the pair carries too little light to be split for a partial shadow.
        let (mut minor, mut small) = (false, false);
        let d = sn.centre - rn.centre;
        let dist = d.length();
        let reach = rn.radius + sn.radius;
        if dist > 0.0 && dist.is_finite() {
            let w = d / dist;
            let gap = (dist - reach).max(0.0) as f64;
            let bound = if gap > 0.0 {
                (self.power[s as usize] * rn.area as f64 / (std::f64::consts::PI * gap * gap))
                    .min(self.power[s as usize])
            } else {
                self.power[s as usize]
            };
            small = bound <= self.small;
            minor = bound <= PARTIAL_SPLIT * self.small;
            let front = fr == Facing::Front && fs == Facing::Front && dist > reach;
            // A pair whose ends are flat and face each other at their centres, but reach
            // across each other's planes (a book's side and the floor around it): a point
            // link gives the part of one end behind the other's plane light it should not
            // get. That is good enough when the ends are small against their distance (the
            // part behind is then seen at a grazing angle) or the transfer too small to
            // matter; closer, they are split.
            let grazing =
                rn.flat() && sn.flat() && rn.normal.dot(w) > 0.0 && sn.normal.dot(w) < 0.0;
            let far = (front || grazing) && reach < self.opening * dist;
            let coherent = self.tree.coherent[r as usize] && self.tree.coherent[s as usize];
            // A pair far apart that cannot be linked (not coherent, or facing mixed) is
            // split; first, when [`CULL_RAYS`] rays all find it hidden (rooms apart, behind
            // a wall), it is dropped whole instead of testing each of its descendants'
            // visibility. The cull is a biased decision (a pair a fraction `v` visible is
            // lost with probability `(1 - v)^CULL_RAYS`); culled pairs are nearly all
            // wholly hidden or wholly visible, and one ray against eight moved the mean
            // of cornell by -0.2 %, of the corridor by -0.06 % and of `building-2x1` by
            // nothing, for 20 % of the building's time. It keeps its own distance
            // whatever the links' opening: culling nearer pairs measured 1.4 % dark on
            // `building-2x1` (rays miss the openings between close clusters).
            let linkable = coherent && (far || (small && (front || grazing)));
            let far_apart = dist > reach && reach < self.cull_opening * dist;
            if !linkable
                && !both_leaves
                && far_apart
                && self.visibility(rn, sn, r, s, CULL_RAYS) <= 0.0
            {
                return Step::Drop;
            }
            if linkable {
                // A link too weak to be split for a partial shadow (a `small` one included)
                // only needs its visibility's expectation: one ray ([`MINOR_RAYS`]); the
                // others get [`HierarchySettings::visibility_rays`], enough to see a
                // partial shadow.
                let rays = if minor {
                    MINOR_RAYS.min(self.settings.visibility_rays)
                } else {
                    self.settings.visibility_rays
                };
                let v = self.visibility(rn, sn, r, s, rays);
                if v <= 0.0 {
                    return Step::Drop;
                }
                // A partly visible link that carries light is split: something stands
                // between its ends, and the link would spread its shadow over them. (Its
                // ends are coherent: no wall runs through either.)
                if v >= 1.0 || minor || !(split_r_ok || split_s_ok) {
                    let g = v / (std::f32::consts::PI * dist * dist);
                    return Step::Far(FarLink {
                        receiver: r,
                        sender: s,
                        w,
                        g,
                    });
                }
            }
        }
        if both_leaves {
            return self.near(r, s);
        }
        if !(split_r_ok || split_s_ok) {
            // At the element budget on both ends (or a cluster and an element).
            let close = dist - reach < rn.radius.max(sn.radius);
            // Samples as the transfer bound asks: one for a link whose bound is below the
            // threshold of links kept at any distance (it only needs an unbiased estimate,
            // as a minor far link's one ray), [`HierarchySettings::visibility_rays`] for
            // one too weak to be split, twice more ([`CLUSTER_SAMPLES`]) for the others.
            // On the Breakfast Room, two in three of the pairs that reach the groups
            // are below the threshold.
            let count = if small {
                1
            } else if minor {
                self.settings.visibility_rays
            } else {
                self.cluster_samples * self.settings.visibility_rays
            };
            return self.cluster(r, s, count, close);
        }
        // Split: the end whose facing is mixed, else the larger.
        let split_r = match (split_r_ok, split_s_ok) {
            (false, _) => false,
            (_, false) => true,
            _ => {
                let (cr, cs) = (
                    self.tree.coherent[r as usize],
                    self.tree.coherent[s as usize],
                );
                match (fr == Facing::Mixed || !cr, fs == Facing::Mixed || !cs) {
                    (true, false) => true,
                    (false, true) => false,
                    _ => rn.radius >= sn.radius,
                }
            }
        };
        if split_r {
            let [a, b] = rn.children;
            Step::Split([(a, s), (b, s), (0, 0), (0, 0)], 2)
        } else {
            let [a, b] = sn.children;
            Step::Split([(r, a), (r, b), (0, 0), (0, 0)], 2)
        }
    }

    /// Whether the refinement may split node `i`: it is a cluster wider than the element
    /// budget ([`HierarchySettings::cluster_radius`]), or a nearly flat one
    /// ([`Node::nearly_flat`]) whose leaves do not see each other ([`Tree::coherence`]). A cluster link gives every leaf of its
    /// receiver the same irradiance and takes every leaf of its sender as sending the mean
    /// radiosity: a few floor pieces split at a wall's foot, on both sides of it, would
    /// carry light under the wall (4.6e-4 of the lit room's light in the leak test,
    /// against 4.2e-5 when they are split). A cluster of furniture whose parts hide each
    /// other stays whole: splitting those took the Breakfast Room's links from 15 to 40
    /// million.
    fn splittable(&self, i: u32) -> bool {
        let node = &self.tree.nodes[i as usize];
        if self.whole_groups {
            return !node.leaf() && !self.tree.in_group[i as usize];
        }
        !node.leaf()
            && (node.radius > self.budget_radius
                || (node.nearly_flat() && !self.tree.coherent[i as usize]))
    }

    /// The cluster link from `s` to `r`. With the sender's radiosity taken as its mean
    /// `Phi / A_s`, a point `x` of the receiver gets `Phi / A_s sum_j F(x, j) V(x, j)` over
    /// the sender's leaves `j` (`F` the closed-form point-to-triangle form factor, exact as
    /// the distance goes to zero where a point-to-point kernel diverges, `V` the visible
    /// fraction), and the link's coefficient is the mean of that over the receiver's area
    /// per unit of the sender's power. Both ends' orientations are the leaves' own: a cup's
    /// inside and outside, a chair's legs facing every way, are each counted where they
    /// face.
    ///
    /// `count` points `x` (stratified over the receiver's leaves by area). Apart (a gap
    /// wider than the larger radius), each takes one point `q` uniform over the sender
    /// (a leaf picked by area, a point on it) and one ray to it: `A_s K(x, q) V(x, q)`,
    /// with `K` the point-to-point kernel ([`Leaf::kernel`]), estimates the sum without
    /// bias, and `K` is bounded there (the closed form at the picked leaf, used before,
    /// cost a quarter of the Breakfast Room's links for the same error). Close (touching
    /// clusters, a cup on a table), one leaf picked by area would put the light of a tiny
    /// leaf next to `x` on one sample in eight, a thousand times too bright: each point
    /// sums over the sender's tree instead (Barnes and Hut's: a node beyond
    /// [`KERNEL_REACH`] radii one kernel term, nearer its children, a leaf its closed form
    /// or kernel, [`leaf_term`]) and estimates the visibility with [`CLOSE_RAYS`] rays to
    /// terms picked in proportion to what they send it.
    fn cluster(&self, r: u32, s: u32, count: u32, close: bool) -> Step {
        let (nodes, leaves) = (&self.tree.nodes, &self.tree.leaves);
        let (rn, sn) = (&nodes[r as usize], &nodes[s as usize]);
        let mut rng = Rng::new(
            hash_seed(self.set ^ 0xc1u64 << 32, r as u64, s as u64),
            0x73,
        );
        // Whether `x` sees a random point of leaf `j` above its tangent plane (the part
        // the form factor counts; a point below would be hidden by `x`'s own surface).
        //
        // Between clusters of mesh elements, a leaf found wholly below after a few tries
        // counts as hidden: its sliver above carries little, and counting it seen let light
        // under a wall (a floor piece across it is such a sliver: the whole piece's
        // radiosity, lit on the far side, sent from the sliver on this side).
        //
        // Between groups ([`Refiner::whole_groups`]), the point is drawn on the part of
        // the triangle above the plane: a group's cluster links are all the light it gets,
        // and the tries lost the light of large sender triangles that straddle the plane
        // right next to `x` (a floor under a panel standing on it): 2.4 % of a cluttered
        // room's first bounce.
        let sees = |x: Vec3, n: Vec3, b: &Leaf, rng: &mut Rng| {
            let q = if self.whole_groups {
                crate::form_factor::point_above(&b.corners, x, n, rng.next_vec2(), rng.next_f32())
            } else {
                (0..HORIZON_TRIES)
                    .map(|_| b.uniform_point(rng.next_vec2()))
                    .find(|&q| n.dot(q - x) > 0.0)
            };
            q.is_some_and(|q| {
                let dist = q.distance(x);
                dist > 0.0 && visibility::sees_surface_point(self.rays, x, n, q, dist)
            })
        };
        // Whether `x` sees the point `q` the kernel was taken at.
        let sees_point = |x: Vec3, n: Vec3, q: Vec3| {
            let dist = x.distance(q);
            dist > 0.0 && visibility::sees_surface_point(self.rays, x, n, q, dist)
        };
        let points = if close {
            (count / CLOSE_SHARE).max(1)
        } else {
            count
        };
        // Apart, point `i` of the receiver takes a leaf of the sender's stratum
        // `i + shift`: pairing strata in order would pair the near parts of the two
        // clusters with each other, and the far with the far, never across.
        let shift = rng.below(points);
        // Close, the sender's nodes that a point's sum visits.
        let mut stack: Vec<u32> = Vec::new();
        let mut sum = 0.0f32;
        let mut terms: Vec<(f32, Target)> = Vec::new();
        // Where the sender's leaves send their own radiosity ([`Refiner::whole_groups`]):
        // each sample's sender leaf and weight (irradiance per unit of its radiosity,
        // summed over the receiver's points before the mean is taken).
        let mut samples: Vec<NearLink> = Vec::new();
        let mut sample = |j: u32, weight: f32| {
            if let Some(last) = samples.iter_mut().find(|l| l.sender == j) {
                last.f += weight;
            } else {
                samples.push(NearLink {
                    receiver: r,
                    sender: j,
                    f: weight,
                });
            }
        };
        for i in 0..points {
            let u = (i as f32 + rng.next_f32()) / points as f32;
            let a = self.tree.leaf(rn, u);
            let own = a.element;
            let x = a.uniform_point(rng.next_vec2());
            if !close {
                let stratum = (i + shift) % points;
                let v = (stratum as f32 + rng.next_f32()) / points as f32;
                let b = self.tree.leaf(sn, v);
                if b.element == own || b.area <= 0.0 {
                    continue;
                }
                // The kernel at a point uniform over the sender (unbiased, and bounded
                // apart: the doc above).
                let (k, q) = b.kernel(x, a.normal, rng.next_vec2());
                let w = k * sn.area;
                if w > 0.0 && w.is_finite() && sees_point(x, a.normal, q) {
                    sum += w;
                    if self.whole_groups {
                        sample(b.element, w);
                    }
                }
                continue;
            }
            // Close: a sum over the sender's tree (Barnes and Hut's): a node whose
            // centre is more than [`KERNEL_REACH`] times its radius from `x` is one term,
            // the kernel at a point uniform over it (unbiased, and bounded there);
            // nearer, its children; a leaf is its closed form or kernel
            // ([`leaf_term`]). Strata of equal area over the sender's leaves (an
            // earlier rule) weighed a tiny leaf next to `x` by the sender's area over its
            // own: on the Breakfast Room at 256 elements, the lit surfaces' mean moved by
            // 30 % from one draw to another.
            terms.clear();
            let mut unoccluded = 0.0f32;
            stack.clear();
            stack.push(s);
            while let Some(i) = stack.pop() {
                let node = &nodes[i as usize];
                let (f, target) = if node.leaf() {
                    let b = &leaves[node.first as usize];
                    leaf_term(x, a.normal, own, b, &mut rng)
                } else if x.distance_squared(node.centre)
                    > KERNEL_REACH * KERNEL_REACH * node.radius * node.radius
                {
                    let b = self.tree.leaf(node, rng.next_f32());
                    let (k, q) = b.kernel(x, a.normal, rng.next_vec2());
                    (k * node.area, Target::Point(q, b.element))
                } else {
                    stack.extend_from_slice(&node.children);
                    continue;
                };
                if f > 0.0 && f.is_finite() {
                    unoccluded += f;
                    terms.push((unoccluded, target));
                }
            }
            if unoccluded <= 0.0 {
                continue;
            }
            let mut seen = 0;
            for _ in 0..CLOSE_RAYS {
                let pick = rng.next_f32() * unoccluded;
                let at = terms.partition_point(|t| t.0 <= pick).min(terms.len() - 1);
                let (visible, element) = match terms[at].1 {
                    Target::Leaf(b) => (sees(x, a.normal, b, &mut rng), b.element),
                    Target::Point(q, element) => (sees_point(x, a.normal, q), element),
                };
                if visible {
                    seen += 1;
                    if self.whole_groups {
                        sample(element, unoccluded / CLOSE_RAYS as f32);
                    }
                }
            }
            sum += unoccluded * seen as f32 / CLOSE_RAYS as f32;
        }
        let c = sum / (points as f32 * sn.area);
        if self.whole_groups {
            // Leaf by leaf: E = sum_i w_i B_(j_i) / points, each sample weighing the radiosity
            // of the leaf it drew (by area apart, by what it sends close), so that the sunlit
            // part of a group sends the sun's light and its shaded part does not.
            samples.retain_mut(|l| {
                l.f /= points as f32;
                l.f > 0.0 && l.f.is_finite()
            });
            return if samples.is_empty() {
                Step::Drop
            } else {
                Step::Sampled(samples)
            };
        }
        if c > 0.0 && c.is_finite() {
            Step::Cluster(ClusterLink {
                receiver: r,
                sender: s,
                c,
            })
        } else {
            Step::Drop
        }
    }

    /// The visible fraction of `count` rays between points of the two nodes (leaves picked
    /// by area, points uniform on them).
    fn visibility(&self, rn: &Node, sn: &Node, r: u32, s: u32, count: u32) -> f32 {
        let mut rng = Rng::new(hash_seed(self.set, r as u64, s as u64), 0x71);
        let mut seen = 0u32;
        for i in 0..count {
            let u = (i as f32 + rng.next_f32()) / count as f32;
            let v = (i as f32 + rng.next_f32()) / count as f32;
            let (a, b) = (self.tree.leaf(rn, u), self.tree.leaf(sn, v));
            let (x, q) = (
                a.uniform_point(rng.next_vec2()),
                b.uniform_point(rng.next_vec2()),
            );
            let dist = x.distance(q);
            if dist > 0.0 && visibility::sees_surface_point(self.rays, x, a.normal, q, dist) {
                seen += 1;
            }
        }
        seen as f32 / count as f32
    }

    /// The near link from element leaf `s` to element leaf `r`: the closed-form form factor
    /// at the receiver's open points with ray-cast visibility.
    fn near(&self, r: u32, s: u32) -> Step {
        let nodes = &self.tree.nodes;
        let els = &self.meshing.elements;
        let (rj, sj) = (
            self.tree.order[nodes[r as usize].first as usize],
            self.tree.order[nodes[s as usize].first as usize],
        );
        let (e, t) = (&els[rj as usize], &els[sj as usize]);
        let (points, count) = e.open_receiver_points();
        if count == 0 {
            return Step::Drop;
        }
        let per_point = self.settings.near_rays.div_ceil(count as u32);
        let f = points[..count]
            .iter()
            .map(|&(p, x)| {
                point_to_triangle_adaptive(
                    x,
                    e.normal,
                    &t.corners,
                    t.normal,
                    self.rays,
                    (per_point, self.full_at),
                    hash_seed(self.set ^ 0x4e45, ((sj as u64) << 32) | rj as u64, p as u64),
                )
            })
            .sum::<f32>()
            / count as f32;
        if f > 0.0 {
            Step::Near(NearLink {
                receiver: rj,
                sender: sj,
                f,
            })
        } else {
            Step::Drop
        }
    }

    /// Decides `(r, s)`: a link goes into `links` (counted against the budget), a split
    /// returns the pairs to refine.
    fn step(&self, r: u32, s: u32, links: &mut Links) -> Option<([(u32, u32); 4], usize)> {
        match self.decide(r, s) {
            Step::Drop => return None,
            Step::Far(l) => links.far.push(l),
            Step::Near(l) => links.near.push(l),
            Step::Cluster(l) => links.cluster.push(l),
            Step::Sampled(l) => {
                links.sampled.extend(l);
                links.sampled_links += 1;
            }
            Step::Split(pairs, n) => return Some((pairs, n)),
        }
        self.count();
        None
    }

    /// Refines `(r, s)` depth first into `links`.
    fn refine(&self, r: u32, s: u32, links: &mut Links) {
        if self.over.load(Ordering::Relaxed) {
            return;
        }
        if let Some((pairs, n)) = self.step(r, s, links) {
            for &(a, b) in &pairs[..n] {
                self.refine(a, b, links);
            }
        }
    }

    fn count(&self) {
        if self.links.fetch_add(1, Ordering::Relaxed) + 1 > self.settings.max_links {
            self.over.store(true, Ordering::Relaxed);
        }
    }

    /// All links of the set, sorted by receiver then sender (whatever the thread count).
    /// `done` is told the share of the pairs refined, after each of 32 parts.
    fn links(&self, done: &mut dyn FnMut(f64)) -> Result<Links, RelightError> {
        let mut all = Links::default();
        if self.tree.nodes.is_empty() {
            return Ok(all);
        }
        // Breadth first until there is work for every thread, then depth first in parallel.
        let mut frontier = vec![(0u32, 0u32)];
        while !frontier.is_empty() && frontier.len() < 4096 {
            let mut next = Vec::new();
            for &(r, s) in &frontier {
                if let Some((pairs, n)) = self.step(r, s, &mut all) {
                    next.extend_from_slice(&pairs[..n]);
                }
            }
            frontier = next;
        }
        // Each part's links join the whole as soon as its part of the frontier is refined,
        // in the frontier's order (the same whatever the thread count): holding every
        // part until the end, then the whole, took 2.7x the links' bytes at once (the
        // Breakfast Room's 76 MB of links, 207 MB more resident).
        let chunk = frontier.len().div_ceil(32).max(1);
        for (i, pairs) in frontier.chunks(chunk).enumerate() {
            let parts: Vec<Links> = pairs
                .par_iter()
                .map(|&(r, s)| {
                    let mut links = Links::default();
                    self.refine(r, s, &mut links);
                    links
                })
                .collect();
            for part in parts {
                all.far.extend(part.far);
                all.near.extend(part.near);
                all.cluster.extend(part.cluster);
                all.sampled.extend(part.sampled);
                all.sampled_links += part.sampled_links;
            }
            done(((i + 1) * chunk).min(frontier.len()) as f64 / frontier.len() as f64);
        }
        if self.over.load(Ordering::Relaxed) {
            return Err(RelightError::Budget(scene_core::BudgetExceeded {
                what: "the hierarchical solve's links".into(),
                needed: self.links.load(Ordering::Relaxed) as u64,
                limit: self.settings.max_links as u64,
                unit: "links",
                hint: "raise HierarchySettings::max_links, or raise opening or link_error".into(),
            }));
        }
        all.far.par_sort_unstable_by_key(|l| (l.receiver, l.sender));
        all.near
            .par_sort_unstable_by_key(|l| (l.receiver, l.sender));
        all.cluster
            .par_sort_unstable_by_key(|l| (l.receiver, l.sender));
        all.sampled
            .par_sort_unstable_by_key(|l| (l.receiver, l.sender));
        Ok(all)
    }
}

/// The links of one set as the refinement makes them.
#[derive(Default)]
struct Links {
    far: Vec<FarLink>,
    near: Vec<NearLink>,
    cluster: Vec<ClusterLink>,
    sampled: Vec<NearLink>,
    /// Cluster links kept as `sampled`.
    sampled_links: usize,
}

/// The hierarchical solve of `meshing` for `sources` (from [`crate::solver::solve_with`],
/// whose checks have run). `progress` gets the share of the solve left, from 1 to 0: the
/// emitters' links to 0.95, the reflected light's links to 0.1 (by the pairs refined), the
/// bounces to 0 (by the log of the power a bounce adds against the tolerance).
pub(crate) fn solve(
    scene: &Scene,
    meshing: &Meshing,
    rays: &RayScene,
    sources: Vec<Source>,
    settings: &SolverSettings,
    hierarchy: &HierarchySettings,
    progress: &mut dyn FnMut(f64),
) -> Result<Solution, RelightError> {
    hierarchy.check()?;
    let start = Instant::now();
    let (n, k) = (meshing.elements.len(), sources.len());
    let els = &meshing.elements;
    let mut stats = HierarchyStats::default();
    let t = Instant::now();
    let by_group = !meshing.groups.is_identity()
        && n as f64 > hierarchy.solve_groups_above as f64 * meshing.groups.count as f64;
    let tree = Tree::build(meshing, rays, by_group);
    stats.tree_time = t.elapsed();
    stats.nodes = tree.nodes.len();
    let node_bytes = tree.nodes.len() * k * NODE_SOURCE_BYTES;
    let limit = crate::mesh::MeshBudget::default().max_solution_bytes;
    if node_bytes as u64 > limit {
        return Err(RelightError::Budget(scene_core::BudgetExceeded {
            what: format!(
                "the hierarchical solve's node vectors ({} nodes, {k} sources)",
                tree.nodes.len()
            ),
            needed: node_bytes as u64,
            limit,
            unit: "bytes",
            hint: "fewer elements (MeshSettings::target_elements) or light banks".into(),
        }));
    }
    let source_of = |id: LightId| sources.iter().position(|s| s.lights.contains(&id));
    // Emission (radiosity pi L) per element and source, and the analytic lights' direct
    // irradiance.
    let mut emission = vec![Vec3::ZERO; n * k];
    for patch in &meshing.patches {
        if let Some(m) = patch.light.and_then(source_of) {
            let first = patch.first_element as usize;
            for j in first..first + patch.element_count as usize {
                if !els[j].hidden {
                    emission[j * k + m] = els[j].emission * std::f32::consts::PI;
                }
            }
        }
    }
    let t = Instant::now();
    let extent = scene.extent();
    let mut direct = vec![Vec3::ZERO; n * k];
    crate::solver::analytic_direct(scene, meshing, rays, &sources, &mut direct);
    stats.analytic_time = t.elapsed();
    let indirect = vec![Vec3::ZERO; n * k];
    if k == 0 || tree.nodes.is_empty() {
        stats.link_bytes = 0;
        return Ok(finish(
            sources,
            n,
            direct,
            indirect,
            vec![Vec3::ZERO; k],
            stats,
            0.0,
            start,
        ));
    }
    let node_power = |leaf_power: &dyn Fn(usize) -> f64| -> Vec<f64> {
        let mut power = vec![0.0f64; tree.nodes.len()];
        for (i, node) in tree.nodes.iter().enumerate().rev() {
            power[i] = if node.leaf() {
                leaf_power(tree.order[node.first as usize] as usize)
            } else {
                power[node.children[0] as usize] + power[node.children[1] as usize]
            };
        }
        power
    };
    let links = AtomicUsize::new(0);
    let over = AtomicBool::new(false);
    // The element budget: nodes no wider than a target element (times the setting).
    let budget_radius = hierarchy.cluster_radius
        * (meshing.patch_area.max(0.0) / (4.0 * std::f32::consts::PI)).sqrt();
    // With the elements grouped, the reflected light's links end at the groups or above.
    let grouped = !tree.in_group.is_empty();
    stats.by_group = grouped;
    // The budget nodes: the coarsest nodes that are elements or no wider than the budget
    // (the groups where grouped).
    stats.budget_nodes = {
        let mut stack = if tree.nodes.is_empty() {
            vec![]
        } else {
            vec![0u32]
        };
        let mut count = 0;
        while let Some(i) = stack.pop() {
            let node = &tree.nodes[i as usize];
            let incoherent_flat = node.nearly_flat() && !tree.coherent[i as usize];
            let at_budget = if grouped {
                tree.in_group[i as usize]
            } else {
                node.radius <= budget_radius && !incoherent_flat
            };
            if node.leaf() || at_budget {
                count += 1;
            } else {
                stack.extend(node.children);
            }
        }
        count
    };
    // `scale` scales the opening criteria: 1 for reflected light, a half for the emitters.
    let refiner = |power: &[f64],
                   set: u64,
                   scale: f32,
                   done: &mut dyn FnMut(f64)|
     -> Result<Links, RelightError> {
        let r = Refiner {
            tree: &tree,
            meshing,
            rays,
            power,
            small: hierarchy.link_error * power.first().copied().unwrap_or(0.0),
            settings: hierarchy,
            opening: scale * hierarchy.opening,
            cull_opening: scale * CULL_OPENING.min(hierarchy.opening),
            budget_radius,
            whole_groups: grouped && set == 2,
            // The emitters' light is not normalised (its sums are not known in advance):
            // twice the samples.
            cluster_samples: CLUSTER_SAMPLES * if set == 1 { 2 } else { 1 },
            full_at: settings.full_visibility_at,
            tol: 1e-6 * extent,
            set,
            links: &links,
            over: &over,
        };
        r.links(done)
    };
    let t = Instant::now();
    progress(1.0);
    let area = |j: usize| els[j].area as f64;
    let lum =
        |v: &[Vec3], j: usize| -> f64 { (0..k).map(|m| luminance(v[j * k + m]) as f64).sum() };
    let total_area: f64 = tree.area_prefix.last().copied().unwrap_or(0.0);
    let emit_power = node_power(&|j| lum(&emission, j) * area(j));
    let direct_links = refiner(&emit_power, 1, 0.5, &mut |d| progress(1.0 - 0.05 * d))?;
    let (slots, direct_links) = GatherTree::compact(&tree, direct_links);
    let direct_links = LinkSet::new(direct_links, slots.len(), n);
    stats.link_time += t.elapsed();
    let t = Instant::now();
    let mut direct_emit = vec![Vec3::ZERO; n * k];
    if emit_power[0] > 0.0 {
        // The emitters' links end anywhere in the tree: a gather of its own, for this
        // step only.
        let mut gather = Gather::new(slots.len(), k);
        gather.run(
            (&slots, &tree),
            meshing,
            &direct_links,
            &emission,
            &mut direct_emit,
        );
        stats.node_bytes = slots.len() * k * NODE_SOURCE_BYTES;
    }
    direct
        .par_iter_mut()
        .zip(direct_emit.par_iter())
        .for_each(|(d, e)| *d += *e);
    drop((direct_emit, emission, slots));
    stats.gather_time += t.elapsed();
    // The radiosity the reflection links are refined against: what the direct light
    // leaves, times the bounces a mean albedo adds, and a floor for surfaces the direct
    // light misses (they receive the indirect light).
    let rho_mean: f64 = tree
        .order
        .iter()
        .map(|&j| luminance(els[j as usize].albedo) as f64 * area(j as usize))
        .sum::<f64>()
        / total_area.max(f64::MIN_POSITIVE);
    let boost = 1.0 / (1.0 - rho_mean.min(0.95));
    let reflected = |j: usize| luminance(els[j].albedo) as f64 * lum(&direct, j) * area(j);
    let first_power: f64 = (0..n).map(reflected).sum();
    let floor = rho_mean * boost * first_power / total_area.max(f64::MIN_POSITIVE);
    let refl_power = node_power(&|j| {
        (reflected(j) * boost + luminance(els[j].albedo) as f64 * floor * area(j)).max(0.0)
    });
    let t = Instant::now();
    let refl_links = refiner(&refl_power, 2, 1.0, &mut |d| progress(0.95 - 0.85 * d))?;
    // The gather runs over the nodes where links end and their ancestors alone
    // ([`GatherTree::compact`]; between groups, the groups or above).
    let (slots, refl_links) = GatherTree::compact(&tree, refl_links);
    let refl_links = LinkSet::new(refl_links, slots.len(), n);
    stats.gather_nodes = slots.len();
    stats.node_bytes = stats.node_bytes.max(slots.len() * k * NODE_SOURCE_BYTES);
    let mut gather = Gather::new(slots.len(), k);
    stats.link_time += t.elapsed();
    stats.direct_far_links = direct_links.far.len();
    stats.direct_near_links = direct_links.near.len();
    stats.far_links = refl_links.far.len();
    stats.near_links = refl_links.near.len();
    stats.direct_cluster_links = direct_links.cluster.len() + direct_links.sampled_links;
    stats.cluster_links = refl_links.cluster.len() + refl_links.sampled_links;
    stats.link_bytes = direct_links.bytes() + refl_links.bytes();
    drop(direct_links);
    // Bounces: delta_{t+1} = gather(rho delta_t), starting from the direct light.
    let t = Instant::now();
    let mut indirect = indirect;
    let reflect = |e: &[Vec3], out: &mut [Vec3]| {
        out.par_chunks_mut(k).enumerate().for_each(|(j, o)| {
            let rho = els[j].albedo;
            for m in 0..k {
                o[m] = if els[j].hidden {
                    Vec3::ZERO
                } else {
                    rho * e[j * k + m]
                };
            }
        });
    };
    let power_of = |e: &[Vec3]| -> f64 {
        (0..n)
            .map(|j| luminance(els[j].albedo) as f64 * lum(e, j) * area(j))
            .sum()
    };
    // Each element's sum of form factors over the links: what it would receive if every
    // surface had unit radiosity. It should be the share of its cosine-weighted hemisphere
    // that other surfaces cover (1 in a closed room; less where it sees the sky through a
    // window), which [`closedness`] measures by rays. Far links treat their ends as
    // points, cluster links give every leaf of a cluster the cluster's mean, and culled
    // pairs are gone: the sums spread by tens of per cent around it (a cluttered room's
    // elements from 0.5 to 1.5). Each element's gathered light is scaled by the ratio of
    // the two, so that no element gains energy (at an albedo near 1 every bounce would
    // grow otherwise) and none loses what its links missed. Scaling only the sums above it
    // (an earlier rule) took 2-3 % of a cluttered room's indirect light.
    //
    // Where the element budget grouped the elements, the ratio is the group's (its sums
    // and closedness each over its leaves by area): a cluster link gives every leaf of a
    // group the group's mean, so a leaf's own sum is not its own, and the ratio of a
    // leaf's closedness to its group's mean sum moved light from a group's open leaves to
    // its closed ones. The group's closedness is then cast from the group as a whole
    // ([`closedness::CLOSED_GROUP_RAYS`], points by area over its leaves), not from each leaf: on the
    // Breakfast Room, 4 610 groups of 375 909 mesh elements.
    let normalise: Vec<f32> = {
        // A gather of one source at unit radiosity (the per-source sums are the same for
        // every source): over the compact slots it holds a few MB (the building's 67 563
        // slots, 6.5 MB), where through the bounces' gather it held two more `n k` vectors.
        let ones: Vec<Vec3> = els
            .iter()
            .map(|e| if e.hidden { Vec3::ZERO } else { Vec3::ONE })
            .collect();
        let mut sums = vec![Vec3::ZERO; n];
        Gather::new(slots.len(), 1).run((&slots, &tree), meshing, &refl_links, &ones, &mut sums);
        drop(ones);
        let ratio = |c: f64, s: f64| {
            if s > 0.0 {
                ((c / s) as f32).min(NORMALISE_MAX)
            } else {
                1.0
            }
        };
        if grouped {
            let groups = &meshing.groups;
            // The mesh elements the links reach, whose sums and closedness count.
            let reached: Vec<bool> = sums.iter().map(|s| s.x > 0.0).collect();

            let closed = closedness(scene, meshing, rays, extent, Some((groups, &reached)));
            let mut totals = vec![0.0f64; groups.count];
            for (j, e) in els.iter().enumerate() {
                if reached[j] && !e.hidden && e.area > 0.0 {
                    totals[groups.of(j)] += sums[j].x as f64 * e.area as f64;
                }
            }
            (0..n)
                .map(|j| {
                    let g = groups.of(j);
                    closed[g].map_or(1.0, |c| ratio(c, totals[g]))
                })
                .collect()
        } else {
            let closed = closedness(scene, meshing, rays, extent, None);
            sums.iter()
                .zip(&closed)
                .map(|(s, &c)| c.map_or(1.0, |c| ratio(c, s.x as f64)))
                .collect()
        }
    };

    let mut b = vec![Vec3::ZERO; n * k];
    let mut delta = vec![Vec3::ZERO; n * k];
    reflect(&direct, &mut b);
    let mut fraction = if first_power > 0.0 { 1.0 } else { 0.0 };
    // The ratio of the last bounce's power to the one before.
    let mut ratio = 0.0f64;
    while fraction > hierarchy.tolerance && stats.bounces < hierarchy.max_bounces {
        gather.run((&slots, &tree), meshing, &refl_links, &b, &mut delta);
        delta
            .par_chunks_mut(k)
            .zip(normalise.par_iter())
            .for_each(|(d, &f)| {
                if f != 1.0 {
                    d.iter_mut().for_each(|v| *v *= f);
                }
            });
        indirect
            .par_iter_mut()
            .zip(delta.par_iter())
            .for_each(|(i, d)| *i += *d);
        stats.bounces += 1;
        let p = power_of(&delta);
        crate::solver::check_energy(stats.bounces, p / first_power)?;
        ratio = p / first_power / fraction;
        fraction = p / first_power;
        reflect(&delta, &mut b);
        let bounced = (fraction.ln() / hierarchy.tolerance.ln()).clamp(0.0, 1.0);
        progress(0.1 * (1.0 - bounced));
    }
    // The bounces not iterated, where the settings ask for the ambient term: each element's
    // last bounce times the geometric series of the bounce ratio, `q / (1 - q)`. Unlike
    // Cohen's uniform term (the progressive solve's), it stays where the light went: an
    // element the last bounce did not reach gets nothing (a uniform term would light every
    // element some stray link touched, a room behind a wall included).
    let mut ambient = vec![Vec3::ZERO; k];
    if settings.ambient && fraction > 0.0 && ratio.is_finite() {
        let q = ratio.clamp(0.0, 0.95) as f32;
        let series = q / (1.0 - q);
        indirect
            .par_iter_mut()
            .zip(delta.par_iter())
            .for_each(|(i, d)| *i += *d * series);
        for (m, a) in ambient.iter_mut().enumerate() {
            let sum: Vec3 = (0..n).map(|j| delta[j * k + m] * els[j].area).sum();
            *a = sum * series / total_area as f32;
        }
    }
    stats.gather_time += t.elapsed();
    progress(0.0);
    Ok(finish(
        sources, n, direct, indirect, ambient, stats, fraction, start,
    ))
}

#[allow(clippy::too_many_arguments)]
fn finish(
    sources: Vec<Source>,
    n: usize,
    direct: Vec<Vec3>,
    indirect: Vec<Vec3>,
    ambient: Vec<Vec3>,
    hierarchy: HierarchyStats,
    fraction: f64,
    start: Instant,
) -> Solution {
    Solution {
        sources,
        elements: n,
        direct,
        indirect,
        ambient,
        stats: SolveStats {
            unshot_fraction: fraction,
            time: start.elapsed(),
            hierarchy: Some(hierarchy),
            ..Default::default()
        },
    }
}

#[cfg(test)]
mod tests {
    use super::tree::orientation_class;
    use super::*;

    #[test]
    fn orientation_classes_put_axes_at_cell_centres() {
        assert_eq!(orientation_class(Vec3::X), 4);
        assert_eq!(orientation_class(Vec3::NEG_Y), 3 * 9 + 4);
        // A normal 40 degrees off +Z leaves the centre cell.
        let tilted = Vec3::new(40f32.to_radians().sin(), 0.0, 40f32.to_radians().cos());
        assert_ne!(orientation_class(tilted), 4 * 9 + 4);
    }

    fn node(centre: Vec3, radius: f32, normal: Vec3, cone: f32) -> Node {
        Node {
            first: 0,
            count: 2,
            children: [1, 2],
            centre,
            radius,
            lo: centre - radius,
            hi: centre + radius,
            normal,
            cone,
            cone_sin_cos: [cone.sin(), cone.cos()],
            plane: [0.0; 2],
            area: 1.0,
        }
    }

    /// The cone test through cosines agrees with the angles it stands for
    /// (`angle + cone + asin(reach / dist)` against a right angle), away from the
    /// boundaries where rounding decides.
    #[test]
    fn facing_through_cosines_matches_the_angles() {
        let mut rng = Rng::new(5, 1);
        let unit = |rng: &mut Rng| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5;
        let mut seen = [0usize; 3];
        for _ in 0..20_000 {
            let cone = rng.next_f32() * 1.2;
            let normal = unit(&mut rng).normalize();
            let a = node(Vec3::ZERO, 0.5, normal, cone);
            let dir = unit(&mut rng).normalize();
            let b = node(dir * (1.0 + 9.0 * rng.next_f32()), 0.5, Vec3::Y, 0.5);
            let dist = b.centre.length();
            let beta = ((a.radius + b.radius) / dist).min(1.0).asin();
            let angle = normal.dot(dir).clamp(-1.0, 1.0).acos();
            let half = std::f32::consts::FRAC_PI_2;
            let (front, behind) = (angle + cone + beta - half, angle - cone - beta - half);
            if front.abs() < 1e-4 || behind.abs() < 1e-4 {
                continue;
            }
            let expected = if front < 0.0 {
                Facing::Front
            } else if behind > 0.0 {
                Facing::Behind
            } else {
                Facing::Mixed
            };
            assert_eq!(
                facing(&a, &b, None, 1e-6),
                expected,
                "cone {cone} angle {angle}"
            );
            seen[expected as usize] += 1;
        }
        // Every outcome was exercised.
        assert!(seen.iter().all(|&n| n > 100), "{seen:?}");
    }

    /// A flat node lying in another's plane (the floor beside the floor) is behind it:
    /// every leaf sees it edge-on; one rising out of the plane is in front.
    #[test]
    fn a_node_in_the_plane_is_behind_and_one_above_it_in_front() {
        let mut floor = node(Vec3::ZERO, 0.5, Vec3::Y, 0.0);
        floor.plane = [0.0, 0.0];
        let mut beside = node(Vec3::new(3.0, 0.0, 0.0), 0.5, Vec3::Y, 0.0);
        beside.lo.y = 0.0;
        beside.hi.y = 0.0;
        assert_eq!(facing(&floor, &beside, None, 1e-6), Facing::Behind);
        let wall = [
            Vec3::new(3.0, 0.0, 0.0),
            Vec3::new(3.0, 0.0, 1.0),
            Vec3::new(3.0, 1.0, 0.0),
        ];
        assert_eq!(facing(&floor, &beside, Some(&wall), 1e-6), Facing::Front);
    }
}
