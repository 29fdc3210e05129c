//! Merging coplanar triangles before meshing.
//!
//! Radiosity meshes a scene's *surfaces* at the resolution its light needs (section 2.2);
//! the input's tessellation should not decide it. A scene as users have them often cuts
//! flat walls into fine grids (the built-in `building` cuts every wall, floor and ceiling
//! into 10 cm cells: 264 000 of its 279 084 triangles), and since every scene triangle
//! becomes at least one patch of four elements, such a scene meshed into more than a
//! million elements whatever the target, and the solve never finished.
//!
//! [`merge_coplanar`] removes vertices that lie inside a flat region (or on a straight
//! stretch of its border) by collapsing each onto a neighbour, so that the region keeps its
//! exact shape, holes and all, with far fewer triangles. A vertex is removed only when
//! everything it touches agrees: one mesh, one material, flat shading normals, one plane,
//! texture coordinates affine over its triangles (so interpolating the kept vertices' UVs
//! gives the same texture), and a fan that is a disk or a half-disk. The new triangles must
//! keep their orientation and not be degenerate; of the candidate neighbours the one whose
//! worst new triangle is the best shaped is taken. Curved surfaces, seams and shared edges
//! between different materials are left as they are, and so are meshes whose vertex
//! colours (`Mesh::colors`) vary. The output keeps every mesh (in
//! order, so emissive-mesh light ids still hold), its vertex arrays and the materials;
//! only the triangle lists change.

use std::collections::HashMap;

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use scene_core::{Mesh, Scene};

/// What [`merge_coplanar`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MergeStats {
    /// Scene triangles before.
    pub triangles_before: usize,
    /// Triangles after.
    pub triangles_after: usize,
    /// Vertices removed (one collapse each).
    pub vertices_removed: usize,
}

/// A scene with coplanar triangles merged, and for every triangle of it (global order) the
/// global id of the first scene triangle it came from.
#[derive(Clone, Debug)]
pub struct Merged {
    /// The merged scene: same meshes, vertices, materials, textures and lights.
    pub scene: Scene,
    /// For each merged triangle (global id), a scene triangle of its flat region: the
    /// smallest global id among the input triangles merged into it or into the triangles
    /// it took area from.
    pub origin: Vec<u32>,
    /// Counts.
    pub stats: MergeStats,
}

/// Merges coplanar triangles of `scene` (see the module documentation). Deterministic:
/// meshes are merged independently (in parallel), each one sequentially in vertex order.
pub fn merge_coplanar(scene: &Scene) -> Merged {
    let mut first = Vec::with_capacity(scene.meshes.len());
    let mut global = 0u32;
    for m in &scene.meshes {
        first.push(global);
        global += m.indices.len() as u32;
    }
    let merged: Vec<MergedMesh> = scene.meshes.par_iter().map(merge_mesh).collect();
    let mut out = scene.clone();
    let mut origin = Vec::new();
    let mut removed = 0;
    for (mi, (indices, materials, from, r)) in merged.into_iter().enumerate() {
        origin.extend(from.iter().map(|&t| first[mi] + t));
        out.meshes[mi].indices = indices;
        out.meshes[mi].material_ids = materials;
        removed += r;
    }
    let stats = MergeStats {
        triangles_before: scene.triangle_count(),
        triangles_after: origin.len(),
        vertices_removed: removed,
    };
    Merged {
        scene: out,
        origin,
        stats,
    }
}

/// Cosine above which two triangle normals count as one plane (about 0.08 degrees).
const SAME_PLANE_COS: f32 = 1.0 - 1e-6;

/// The worst shape a collapse may leave ([`quality`]; 1e-3 is a triangle about 1 000 times
/// longer than it is wide): a collapse never makes a needle that the input did not have.
const MIN_QUALITY: f32 = 1e-3;

/// One triangle of the mesh being merged.
#[derive(Clone, Copy)]
struct Tri {
    /// Welded vertex ids, counter-clockwise.
    v: [u32; 3],
    /// The input vertex index at each corner (whose normal and UV the output keeps).
    corner: [u32; 3],
    material: u32,
    /// Smallest input triangle index it covers.
    origin: u32,
    /// Unit winding normal.
    normal: Vec3,
    /// Flat: its vertex normals agree with its winding normal.
    flat: bool,
    /// Changed by a collapse: only such triangles are flipped afterwards, so that a
    /// region with nothing to merge keeps its triangles as they were.
    touched: bool,
    alive: bool,
}

/// Merges one mesh: its triangles (input vertex indices), materials, origins and the
/// number of vertices removed.
/// One mesh merged: its triangles (indices), their material ids, the input triangle each
/// came from, and the vertices removed.
type MergedMesh = (Vec<[u32; 3]>, Vec<u32>, Vec<u32>, usize);

fn merge_mesh(mesh: &Mesh) -> MergedMesh {
    // Vertex colours are interpolated over the triangles as they are: a mesh whose colours
    // vary is left unmerged (one colour everywhere merges as any mesh).
    let varies = mesh
        .colors
        .as_ref()
        .is_some_and(|c| c.iter().any(|&x| x != c[0]));
    if varies {
        let n = mesh.indices.len() as u32;
        return (
            mesh.indices.clone(),
            mesh.material_ids.clone(),
            (0..n).collect(),
            0,
        );
    }
    // Weld by position and texture coordinate (bit for bit): a seam stays a border.
    let mut weld: HashMap<[u32; 5], u32> = HashMap::new();
    let mut pos = Vec::new();
    let mut uv = Vec::new();
    let uvs = mesh.uvs.as_ref();
    let id_of: Vec<u32> = (0..mesh.positions.len())
        .map(|i| {
            let p = mesh.positions[i];
            let t = uvs.map(|u| u[i]).unwrap_or(Vec2::ZERO);
            let key = [p.x, p.y, p.z, t.x, t.y].map(|c| (c + 0.0).to_bits());
            *weld.entry(key).or_insert_with(|| {
                pos.push(p);
                uv.push(t);
                pos.len() as u32 - 1
            })
        })
        .collect();
    let mut tris: Vec<Tri> = mesh
        .indices
        .iter()
        .zip(&mesh.material_ids)
        .enumerate()
        .map(|(t, (idx, &material))| {
            let p = idx.map(|i| mesh.positions[i as usize]);
            let normal = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            let flat = normal != Vec3::ZERO
                && idx.iter().all(|&i| {
                    mesh.normals
                        .get(i as usize)
                        .is_none_or(|n| n.dot(normal) > SAME_PLANE_COS)
                });
            Tri {
                v: idx.map(|i| id_of[i as usize]),
                corner: *idx,
                material,
                origin: t as u32,
                normal,
                flat,
                touched: false,
                alive: true,
            }
        })
        .collect();
    let mut incident: Vec<Vec<u32>> = vec![Vec::new(); pos.len()];
    for (t, tri) in tris.iter().enumerate() {
        if tri.v[0] != tri.v[1] && tri.v[1] != tri.v[2] && tri.v[2] != tri.v[0] {
            for &v in &tri.v {
                incident[v as usize].push(t as u32);
            }
        }
    }
    let textured = uvs.is_some();
    let mut removed = 0;
    loop {
        let before = removed;
        for v in 0..pos.len() as u32 {
            if let Some(u) = best_collapse(&tris, &incident, &pos, &uv, textured, v) {
                collapse(&mut tris, &mut incident, v, u);
                removed += 1;
            }
        }
        if removed == before {
            break;
        }
    }
    delaunay_flips(&mut tris, &pos, &uv, textured);
    let alive = tris.iter().filter(|t| t.alive);
    (
        alive.clone().map(|t| t.corner).collect(),
        alive.clone().map(|t| t.material).collect(),
        alive.map(|t| t.origin).collect(),
        removed,
    )
}

/// Twice the signed area of `a, b, c` seen along `n`.
fn signed_area(a: Vec3, b: Vec3, c: Vec3, n: Vec3) -> f32 {
    (b - a).cross(c - a).dot(n)
}

/// Shape quality of a triangle: 1 for equilateral, towards 0 for slivers.
fn quality(a: Vec3, b: Vec3, c: Vec3, n: Vec3) -> f32 {
    let l = (b - a).length_squared() + (c - b).length_squared() + (a - c).length_squared();
    if l > 0.0 {
        2.0 * 3f32.sqrt() * signed_area(a, b, c, n) / l
    } else {
        0.0
    }
}

/// The neighbour that vertex `v` can collapse onto without changing the surface, the best
/// shaped of them, or `None`.
fn best_collapse(
    tris: &[Tri],
    incident: &[Vec<u32>],
    pos: &[Vec3],
    uv: &[Vec2],
    textured: bool,
    v: u32,
) -> Option<u32> {
    let fan = &incident[v as usize];
    if fan.is_empty() || fan.len() > 64 {
        return None;
    }
    let x = pos[v as usize];
    // Rounding of the coordinates themselves (a grid at 10 cm is not exact in binary):
    // lengths below this count as zero.
    let mut reach = 0.0f32;
    for &t in fan {
        for w in tris[t as usize].v {
            reach = reach.max(pos[w as usize].distance(x));
        }
    }
    let tol = 4.0 * f32::EPSILON * (x.abs().max_element() + reach);
    // The fan in groups of one plane and material: one group (v inside a flat region or on
    // a straight stretch of its border), or several that all border on one straight line
    // through v (a crease: the edge of a box whose faces are grids).
    let mut groups: Vec<Vec<u32>> = Vec::new();
    for &t in fan {
        let tri = &tris[t as usize];
        if !tri.flat {
            return None;
        }
        match groups.iter_mut().find(|g| {
            let first = &tris[g[0] as usize];
            first.material == tri.material && first.normal.dot(tri.normal) > SAME_PLANE_COS
        }) {
            Some(g) => g.push(t),
            None => groups.push(vec![t]),
        }
    }
    let mut candidates: Option<Vec<u32>> = None;
    for group in &groups {
        let found = group_candidates(
            tris,
            pos,
            uv,
            textured,
            (v, x, tol),
            group,
            groups.len() > 1,
        )?;
        candidates = Some(match candidates {
            None => found,
            Some(c) => c.into_iter().filter(|u| found.contains(u)).collect(),
        });
    }
    let candidates = candidates?;
    let neighbours = |w: u32| -> Vec<u32> {
        let mut out: Vec<u32> = incident[w as usize]
            .iter()
            .flat_map(|&t| tris[t as usize].v)
            .filter(|&q| q != w)
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    };
    let nv = neighbours(v);
    let area_of = |t: u32| {
        let tri = &tris[t as usize];
        let [a, b, c] = tri.v.map(|w| pos[w as usize]);
        signed_area(a, b, c, tri.normal)
    };
    let mut best: Option<(u32, f32)> = None;
    for u in candidates {
        // Link condition: the vertices next to both are the far corners of the
        // triangles on the edge v-u (else the collapse folds the surface).
        let shared: Vec<u32> = fan
            .iter()
            .filter(|&&t| tris[t as usize].v.contains(&u))
            .flat_map(|&t| tris[t as usize].v)
            .filter(|&q| q != u && q != v)
            .collect();
        let nu = neighbours(u);
        let common = nv.iter().filter(|q| nu.binary_search(q).is_ok()).count();
        if common != shared.len() {
            continue;
        }
        let mut worst = f32::INFINITY;
        for &t in fan {
            let tri = &tris[t as usize];
            if tri.v.contains(&u) {
                continue;
            }
            let n = tri.normal;
            let group_area: f32 = groups
                .iter()
                .find(|g| g.contains(&t))
                .map_or(0.0, |g| g.iter().map(|&q| area_of(q)).sum());
            let [a, b, c] = tri.v.map(|w| pos[if w == v { u } else { w } as usize]);
            let q = quality(a, b, c, n);
            if signed_area(a, b, c, n) <= 1e-6 * group_area || q < MIN_QUALITY {
                worst = f32::NEG_INFINITY;
                break;
            }
            worst = worst.min(q);
        }
        if worst > 0.0 && best.is_none_or(|(_, q)| worst > q) {
            best = Some((u, worst));
        }
    }
    best.map(|(u, _)| u)
}

/// The neighbours that `v` may collapse onto within one `group` of its fan (one plane,
/// one material), or `None` when the group forbids any collapse: every link vertex in the
/// plane, texture coordinates affine, and the link one cycle (any link vertex; not when
/// `crease`, several groups meeting at v) or one chain whose ends lie on a straight line
/// through `v` (those two ends).
#[allow(clippy::too_many_arguments)]
fn group_candidates(
    tris: &[Tri],
    pos: &[Vec3],
    uv: &[Vec2],
    textured: bool,
    (v, x, tol): (u32, Vec3, f32),
    group: &[u32],
    crease: bool,
) -> Option<Vec<u32>> {
    let t0 = &tris[group[0] as usize];
    let n = t0.normal;
    // Link edges a -> b of each fan triangle (v, a, b), counter-clockwise.
    let mut link = Vec::with_capacity(group.len());
    let mut span = 0.0f32;
    for &t in group {
        let tri = &tris[t as usize];
        let r = tri.v.iter().position(|&w| w == v)?;
        let (a, b) = (tri.v[(r + 1) % 3], tri.v[(r + 2) % 3]);
        link.push((a, b));
        span = span.max(pos[a as usize].distance(x));
    }
    // Every link vertex in the plane (within rounding, or a millionth of the fan's size).
    let flat = tol.max(1e-6 * span);
    if link.iter().any(|&(a, b)| {
        [a, b]
            .iter()
            .any(|&w| (pos[w as usize] - x).dot(n).abs() > flat)
    }) {
        return None;
    }
    // Texture coordinates affine over the fan: fitted on the first triangle, checked at
    // every link vertex.
    if textured && !uv_affine(t0, pos, uv, n, &link) {
        return None;
    }
    for &(a, b) in &link {
        if link.iter().filter(|&&(c, _)| c == a).count() != 1
            || link.iter().filter(|&&(_, d)| d == b).count() != 1
        {
            return None;
        }
    }
    let starts_only: Vec<u32> = link
        .iter()
        .filter(|&&(a, _)| !link.iter().any(|&(_, b)| b == a))
        .map(|&(a, _)| a)
        .collect();
    let ends_only: Vec<u32> = link
        .iter()
        .filter(|&&(_, b)| !link.iter().any(|&(a, _)| a == b))
        .map(|&(_, b)| b)
        .collect();
    match (starts_only.as_slice(), ends_only.as_slice()) {
        ([], []) if !crease => {
            // One cycle, not several: from the first link vertex back to it in exactly
            // as many steps as there are edges.
            let start = link[0].0;
            let mut w = start;
            for step in 1..=link.len() {
                w = link.iter().find(|&&(a, _)| a == w)?.1;
                if w == start && step != link.len() {
                    return None;
                }
            }
            Some(link.iter().map(|&(a, _)| a).collect())
        }
        (&[s], &[e]) => {
            // One chain from s to e through every link edge (no cycle beside it).
            let mut w = s;
            for _ in 0..link.len() {
                w = link.iter().find(|&&(a, _)| a == w)?.1;
            }
            if w != e {
                return None;
            }
            // On the border: only along it, and only where it runs straight.
            // (v within rounding of the line from s to e, between them).
            let (ps, pe) = (pos[s as usize] - x, pos[e as usize] - x);
            let off_line = ps.cross(pe).length() / (pe - ps).length().max(f32::MIN_POSITIVE);
            if off_line > flat || ps.dot(pe) >= 0.0 {
                return None;
            }
            Some(vec![s, e])
        }
        _ => None,
    }
}

/// Whether the texture coordinates of the link vertices are the affine map fitted on the
/// triangle `t0` (within 1e-5 of the fan's UV span).
fn uv_affine(t0: &Tri, pos: &[Vec3], uv: &[Vec2], n: Vec3, link: &[(u32, u32)]) -> bool {
    let [a, b, c] = t0.v.map(|w| pos[w as usize]);
    let [ua, ub, uc] = t0.v.map(|w| uv[w as usize]);
    let area = signed_area(a, b, c, n);
    if area <= 0.0 {
        return false;
    }
    let mut span = (ub - ua).abs().max((uc - ua).abs());
    for &(p, q) in link {
        span = span
            .max((uv[p as usize] - ua).abs())
            .max((uv[q as usize] - ua).abs());
    }
    let tol = 1e-5 * span.max_element().max(1e-6);
    link.iter().flat_map(|&(p, q)| [p, q]).all(|w| {
        let x = pos[w as usize];
        let (l1, l2) = (
            signed_area(a, x, c, n) / area,
            signed_area(a, b, x, n) / area,
        );
        let predicted = ua * (1.0 - l1 - l2) + ub * l1 + uc * l2;
        (predicted - uv[w as usize]).abs().max_element() <= tol
    })
}

/// Collapses `v` onto `u`: the triangles on the edge go, the others of `v`'s fan take `u`
/// (its input vertex from a triangle that had it).
fn collapse(tris: &mut [Tri], incident: &mut [Vec<u32>], v: u32, u: u32) {
    let fan = std::mem::take(&mut incident[v as usize]);
    // u's input vertex as a triangle of the same plane and material has it (at a crease
    // each face has its own, with its own normal).
    let corner_u: Vec<u32> = fan
        .iter()
        .map(|&t| {
            let tri = &tris[t as usize];
            fan.iter()
                .find_map(|&q| {
                    let other = &tris[q as usize];
                    let same = other.material == tri.material
                        && other.normal.dot(tri.normal) > SAME_PLANE_COS;
                    let r = other.v.iter().position(|&w| w == u)?;
                    same.then_some(other.corner[r])
                })
                .expect("every group of the fan has the edge v-u")
        })
        .collect();
    for (&t, &corner_u) in fan.iter().zip(&corner_u) {
        let tri = &mut tris[t as usize];
        if tri.v.contains(&u) {
            tri.alive = false;
            for w in tri.v {
                if w != v {
                    incident[w as usize].retain(|&q| q != t);
                }
            }
        } else {
            let r = tri.v.iter().position(|&w| w == v).expect("in v's fan");
            tri.v[r] = u;
            tri.corner[r] = corner_u;
            tri.touched = true;
            incident[u as usize].push(t);
        }
    }
    // The area of the removed triangles now belongs to the fan's others: they take the
    // smallest origin of the fan.
    let smallest = fan.iter().map(|&t| tris[t as usize].origin).min();
    if let Some(o) = smallest {
        for &t in &fan {
            if tris[t as usize].alive {
                tris[t as usize].origin = tris[t as usize].origin.min(o);
            }
        }
    }
}

/// Flips edges inside flat regions until every such edge is locally Delaunay (the two
/// angles facing it sum to at most pi): of the triangulations of the merged region, this
/// one keeps the smallest angle largest, so the patches cut from it are not needlessly
/// thin. Edges between triangles that could not have merged (another plane, material, UV
/// map or shading) are never flipped.
fn delaunay_flips(tris: &mut [Tri], pos: &[Vec3], uv: &[Vec2], textured: bool) {
    let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
    for (t, tri) in tris.iter().enumerate().filter(|(_, t)| t.alive) {
        for r in 0..3 {
            edges.insert((tri.v[r], tri.v[(r + 1) % 3]), t as u32);
        }
    }
    let angle = |at: Vec3, p: Vec3, q: Vec3| (p - at).angle_between(q - at);
    for _pass in 0..64 {
        let mut flipped = 0;
        for t1 in 0..tris.len() {
            for r in 0..3 {
                let tri1 = tris[t1];
                if !tri1.alive || !tri1.flat {
                    break;
                }
                let (a, b, c) = (tri1.v[r], tri1.v[(r + 1) % 3], tri1.v[(r + 2) % 3]);
                let Some(&t2) = edges.get(&(b, a)) else {
                    continue;
                };
                let t2 = t2 as usize;
                let tri2 = tris[t2];
                if t2 <= t1
                    || !(tri1.touched && tri2.touched)
                    || !tri2.flat
                    || tri2.material != tri1.material
                    || tri2.normal.dot(tri1.normal) <= SAME_PLANE_COS
                {
                    continue;
                }
                let s = tri2.v.iter().position(|&w| w == b).expect("edge b-a");
                let d = tri2.v[(s + 2) % 3];
                if d == c || edges.contains_key(&(c, d)) || edges.contains_key(&(d, c)) {
                    continue;
                }
                let [pa, pb, pc, pd] = [a, b, c, d].map(|w| pos[w as usize]);
                let n = tri1.normal;
                let size = pa.distance(pb).max(pc.distance(pd));
                if (pd - pa).dot(n).abs() > 1e-6 * size {
                    continue;
                }
                if angle(pc, pa, pb) + angle(pd, pb, pa) <= std::f32::consts::PI + 1e-4 {
                    continue;
                }
                let total = signed_area(pa, pb, pc, n) + signed_area(pb, pa, pd, n);
                if signed_area(pa, pd, pc, n) <= 1e-6 * total
                    || signed_area(pd, pb, pc, n) <= 1e-6 * total
                {
                    continue;
                }
                if textured && !uv_affine(&tri1, pos, uv, n, &[(d, d)]) {
                    continue;
                }
                let corner =
                    |tri: &Tri, w: u32| tri.corner[tri.v.iter().position(|&q| q == w).unwrap()];
                let (ca, cb, cc, cd) = (
                    corner(&tri1, a),
                    corner(&tri1, b),
                    corner(&tri1, c),
                    corner(&tri2, d),
                );
                for (p, q) in [(a, b), (b, c), (c, a), (b, a), (a, d), (d, b)] {
                    edges.remove(&(p, q));
                }
                let origin = tri1.origin.min(tri2.origin);
                tris[t1].v = [a, d, c];
                tris[t1].corner = [ca, cd, cc];
                tris[t1].origin = origin;
                tris[t2].v = [d, b, c];
                tris[t2].corner = [cd, cb, cc];
                tris[t2].origin = origin;
                for (t, tri) in [(t1, tris[t1]), (t2, tris[t2])] {
                    for k in 0..3 {
                        edges.insert((tri.v[k], tri.v[(k + 1) % 3]), t as u32);
                    }
                }
                flipped += 1;
            }
        }
        if flipped == 0 {
            break;
        }
    }
}
