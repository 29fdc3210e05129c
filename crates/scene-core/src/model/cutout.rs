//! Alpha-masked surfaces (glTF's `alphaMode: MASK`) as the places that decide visibility
//! see them: a [`Cutouts`] answers "does triangle `t` exist at barycentric `(u, v)`?"
//! without borrowing the scene, so a ray structure, a rasteriser or a meshing pass can hold
//! it. A scene without masked materials gives an empty [`Cutouts`] whose every query is one
//! comparison.

use std::sync::Arc;

use glam::Vec2;

use crate::scene::{Scene, Texture};

/// One masked triangle: its texture coordinates and the mask that cuts it.
#[derive(Clone, Copy, Debug)]
struct CutTriangle {
    uvs: [Vec2; 3],
    mask: u32,
}

/// A masked material: its cutoff and the texture whose alpha it reads (none: alpha 1).
#[derive(Clone, Debug)]
struct Mask {
    cutoff: f32,
    texture: Option<Arc<Texture>>,
}

/// The masked triangles of a scene, by global triangle id ([`Scene::mesh_offsets`]).
#[derive(Clone, Debug, Default)]
pub struct Cutouts {
    /// Per global triangle: index into `triangles`, or `u32::MAX` for an opaque one. Empty
    /// when the scene has no masked triangle.
    slot: Vec<u32>,
    triangles: Vec<CutTriangle>,
    masks: Vec<Mask>,
}

impl Cutouts {
    /// The masked triangles of `scene` (a validated scene; a material id or texture out of
    /// range reads as opaque). Textures are shared, not copied, between the masks that read
    /// them; only their alpha is kept.
    pub fn of(scene: &Scene) -> Self {
        let mut textures: Vec<Option<Arc<Texture>>> = vec![None; scene.textures.len()];
        let mut masks = Vec::new();
        let material_masks: Vec<Option<u32>> = scene
            .materials
            .iter()
            .map(|m| {
                let cutoff = m.alpha_cutoff.filter(|&c| c > 0.0)?;
                let texture = m.albedo_texture.and_then(|t| {
                    let tex = scene.textures.get(t as usize)?;
                    tex.alpha.as_ref()?;
                    let shared = textures[t as usize].get_or_insert_with(|| {
                        Arc::new(Texture {
                            texels: Vec::new(),
                            ..tex.clone()
                        })
                    });
                    Some(shared.clone())
                });
                // Alpha 1 everywhere: opaque up to a cutoff of 1, a hole above it.
                if texture.is_none() && cutoff <= 1.0 {
                    return None;
                }
                masks.push(Mask { cutoff, texture });
                Some(masks.len() as u32 - 1)
            })
            .collect();
        if masks.is_empty() {
            return Self::default();
        }
        Self::build(scene, material_masks, masks)
    }

    fn build(scene: &Scene, material_masks: Vec<Option<u32>>, masks: Vec<Mask>) -> Self {
        let mut slot = Vec::with_capacity(scene.triangle_count());
        let mut triangles = Vec::new();
        for mesh in &scene.meshes {
            for (tri, &material) in mesh.indices.iter().zip(&mesh.material_ids) {
                let Some(mask) = material_masks.get(material as usize).copied().flatten() else {
                    slot.push(u32::MAX);
                    continue;
                };
                let uvs = mesh
                    .uvs
                    .as_ref()
                    .map(|uv| tri.map(|i| uv.get(i as usize).copied().unwrap_or_default()));
                // Without coordinates the alpha is 1 (as `Scene::opaque_at` reads it): such a
                // triangle is a hole only when its cutoff exceeds 1.
                let mask = match uvs {
                    Some(uvs) => CutTriangle { uvs, mask },
                    None if masks[mask as usize].cutoff > 1.0 => CutTriangle {
                        uvs: [Vec2::ZERO; 3],
                        mask,
                    },
                    None => {
                        slot.push(u32::MAX);
                        continue;
                    }
                };
                slot.push(triangles.len() as u32);
                triangles.push(mask);
            }
        }
        if triangles.is_empty() {
            return Self::default();
        }
        Self {
            slot,
            triangles,
            masks,
        }
    }

    /// True when no triangle is masked.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Number of masked triangles.
    pub fn masked_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// True when global triangle `triangle` has a mask.
    pub fn is_masked(&self, triangle: u32) -> bool {
        self.slot
            .get(triangle as usize)
            .is_some_and(|&s| s != u32::MAX)
    }

    /// True where global triangle `triangle` exists at barycentric `b` (of vertices 1 and
    /// 2): always for an unmasked triangle, else where its texture's alpha reaches its
    /// cutoff, as [`Scene::opaque_at`] decides.
    #[inline]
    pub fn opaque(&self, triangle: u32, b: Vec2) -> bool {
        if self.triangles.is_empty() {
            return true;
        }
        let Some(&s) = self.slot.get(triangle as usize) else {
            return true;
        };
        if s == u32::MAX {
            return true;
        }
        let t = &self.triangles[s as usize];
        let mask = &self.masks[t.mask as usize];
        let alpha = match &mask.texture {
            Some(tex) => {
                let uv = t.uvs[0] * (1.0 - b.x - b.y) + t.uvs[1] * b.x + t.uvs[2] * b.y;
                tex.sample_alpha(uv)
            }
            None => 1.0,
        };
        alpha >= mask.cutoff
    }
}

/// The centroids of the `n^2` equal sub-triangles of a triangle's regular subdivision, as
/// barycentric coordinates of vertices 1 and 2: `n^2` points that integrate over the
/// triangle with equal weights.
pub fn triangle_samples(n: u32) -> impl Iterator<Item = Vec2> {
    let inv = 1.0 / n.max(1) as f32;
    (0..n).flat_map(move |i| {
        (0..n - i).flat_map(move |j| {
            // The upward sub-triangle of cell (i, j), and the downward one beside it.
            let up = Vec2::new(i as f32 + 1.0 / 3.0, j as f32 + 1.0 / 3.0) * inv;
            let down = Vec2::new(i as f32 + 2.0 / 3.0, j as f32 + 2.0 / 3.0) * inv;
            std::iter::once(up).chain((i + j + 1 < n).then_some(down))
        })
    })
}

/// The fraction of a triangle that exists, from `n x n` samples ([`triangle_samples`]),
/// each passed to `exists` as barycentric coordinates of vertices 1 and 2. 1 when `n` is 0.
pub fn coverage(n: u32, exists: impl Fn(Vec2) -> bool) -> f32 {
    if n == 0 {
        return 1.0;
    }
    let hits = triangle_samples(n).filter(|&b| exists(b)).count();
    hits as f32 / (n * n) as f32
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::error::SceneError;
    use crate::scene::{Material, Mesh, Sampler};

    /// One unit quad (two triangles, uv = xy) under a 2 x 2 texture whose alpha is
    /// `alpha` (row-major, top row first), masked at `cutoff`.
    fn quad(alpha: [f32; 4], cutoff: Option<f32>, nearest: bool) -> Scene {
        let mut s = Scene::new("mask");
        s.textures.push(Texture {
            name: "a".into(),
            width: 2,
            height: 2,
            texels: vec![Vec3::splat(0.5); 4],
            alpha: Some(alpha.to_vec()),
            sampler: Sampler {
                nearest,
                ..Default::default()
            },
        });
        s.materials.push(Material {
            albedo_texture: Some(0),
            alpha_cutoff: cutoff,
            ..Material::diffuse("m", Vec3::splat(0.5))
        });
        let mut m = Mesh {
            name: "quad".into(),
            uvs: Some(Vec::new()),
            ..Default::default()
        };
        m.push_quad([Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y], 0);
        let uvs = m.positions.iter().map(|p| Vec2::new(p.x, p.y)).collect();
        m.uvs = Some(uvs);
        s.meshes.push(m);
        s
    }

    /// The barycentric coordinates of point `p` (in the quad's plane) in triangle `t`.
    fn bary(s: &Scene, t: usize, p: Vec2) -> Vec2 {
        let m = &s.meshes[0];
        let [a, b, c] = m.indices[t].map(|i| m.positions[i as usize].truncate());
        let (e1, e2, d) = (b - a, c - a, p - a);
        let det = e1.perp_dot(e2);
        Vec2::new(d.perp_dot(e2) / det, e1.perp_dot(d) / det)
    }

    #[test]
    fn alpha_is_filtered_as_colour_and_compared_with_the_cutoff() {
        let s = quad([1.0, 0.0, 0.0, 1.0], Some(0.5), true);
        let t = &s.textures[0];
        // Nearest: texel (0, 0) top-left is 1, (1, 0) is 0.
        assert_eq!(t.sample_alpha(Vec2::new(0.25, 0.25)), 1.0);
        assert_eq!(t.sample_alpha(Vec2::new(0.75, 0.25)), 0.0);
        // Bilinear: halfway between the two texel centres of the top row.
        let b = quad([1.0, 0.0, 0.0, 1.0], Some(0.5), false);
        assert!((b.textures[0].sample_alpha(Vec2::new(0.5, 0.25)) - 0.5).abs() < 1e-6);
        // No alpha reads as 1.
        let mut opaque = t.clone();
        opaque.alpha = None;
        assert_eq!(opaque.sample_alpha(Vec2::new(0.75, 0.25)), 1.0);
        assert!(s.opaque_at(0, Some(Vec2::new(0.25, 0.25))));
        assert!(!s.opaque_at(0, Some(Vec2::new(0.75, 0.25))));
        // Without coordinates the alpha is 1.
        assert!(s.opaque_at(0, None));
    }

    #[test]
    fn cutouts_agree_with_the_scene_and_cover_half_a_checkerboard() {
        let s = quad([1.0, 0.0, 0.0, 1.0], Some(0.5), true);
        let c = Cutouts::of(&s);
        assert_eq!(c.masked_triangles(), 2);
        for p in [(0.2, 0.3), (0.8, 0.1), (0.6, 0.9), (0.1, 0.7), (0.45, 0.55)] {
            let p = Vec2::new(p.0, p.1);
            let want = s.opaque_at(0, Some(p));
            let t = if bary(&s, 0, p).min_element() >= 0.0 && bary(&s, 0, p).element_sum() <= 1.0 {
                0
            } else {
                1
            };
            assert_eq!(c.opaque(t as u32, bary(&s, t, p)), want, "{p}");
        }
        // Each triangle of the quad is half solid (the checkerboard's diagonal cells split
        // evenly along the quad's diagonal).
        for t in 0..2u32 {
            let f = coverage(16, |b| c.opaque(t, b));
            assert!((f - 0.5).abs() < 0.05, "triangle {t}: {f}");
        }
        // Opaque materials, a cutoff of 0 and a scene without masks give no cutouts.
        assert!(Cutouts::of(&quad([0.0; 4], None, true)).is_empty());
        assert!(Cutouts::of(&quad([0.0; 4], Some(0.0), true)).is_empty());
        // A cutoff above 1 is a hole everywhere, even without a texture.
        let mut hole = quad([1.0; 4], Some(1.5), true);
        hole.materials[0].albedo_texture = None;
        let c = Cutouts::of(&hole);
        assert!(!c.opaque(0, Vec2::splat(0.2)) && !c.opaque(1, Vec2::splat(0.2)));
    }

    #[test]
    fn coverage_counts_equal_sub_triangles() {
        // The part with s < 1/2 holds 3/4 of the triangle's area (1 - (1/2)^2).
        for n in [2, 4, 8] {
            assert_eq!(coverage(n, |b| b.x < 0.5), 0.75, "n = {n}");
        }
        assert_eq!(coverage(8, |_| true), 1.0);
        assert_eq!(coverage(0, |_| false), 1.0);
        assert_eq!(triangle_samples(5).count(), 25);
        let mean: Vec2 = triangle_samples(6).sum::<Vec2>() / 36.0;
        assert!((mean - Vec2::splat(1.0 / 3.0)).length() < 1e-6, "{mean}");
    }

    #[test]
    fn bad_cutoffs_and_alpha_are_refused() {
        for c in [-0.1, f32::NAN, f32::INFINITY] {
            let mut s = quad([1.0; 4], Some(c), true);
            let e = s.validate().unwrap_err();
            assert!(matches!(e, SceneError::InvalidMaterial { .. }), "{c}: {e}");
        }
        let mut s = quad([1.0, 2.0, 0.0, 0.0], Some(0.5), true);
        assert!(matches!(
            s.validate(),
            Err(SceneError::InvalidTexture { .. })
        ));
        let mut s = quad([1.0; 4], Some(0.5), true);
        s.textures[0].alpha = Some(vec![1.0; 3]);
        let e = s.validate().unwrap_err();
        assert!(e.to_string().contains("3 alpha values for 4 texels"), "{e}");
    }
}
