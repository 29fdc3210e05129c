//! The G-buffer, the project's currency (thesis figure 4.1), and the trait of renderers
//! that produce it.

use glam::{Vec3, Vec4};

use crate::Error;
use crate::scene::Scene;
use crate::view::{HemicubeFace, View};

/// Triangle id stored for background pixels.
pub const BACKGROUND_ID: u32 = u32::MAX;

/// A CPU G-buffer: per pixel, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct GBuffer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB albedo in `xyz`; `w` is the radiation mask of the thesis (1 where the
    /// surface takes part in radiosity exchange, 0 on background).
    pub albedo: Vec<Vec4>,
    /// Unit world-space normal (zero on background).
    pub normal: Vec<Vec3>,
    /// Linear depth: distance along the view direction divided by the far plane (section
    /// 4.3); 1 on background.
    pub depth: Vec<f32>,
    /// Global triangle id (meshes numbered in order, see [`Scene::mesh_offsets`]), or
    /// [`BACKGROUND_ID`].
    pub triangle_id: Vec<u32>,
}

impl GBuffer {
    /// A G-buffer holding only background.
    pub fn background(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Self {
            width,
            height,
            albedo: vec![Vec4::ZERO; n],
            normal: vec![Vec3::ZERO; n],
            depth: vec![1.0; n],
            triangle_id: vec![BACKGROUND_ID; n],
        }
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// True for a zero-size buffer.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// True where no geometry was hit (the thesis' stencil background mask).
    pub fn is_background(&self, index: usize) -> bool {
        self.triangle_id[index] == BACKGROUND_ID
    }

    /// The background mask for all pixels.
    pub fn background_mask(&self) -> Vec<bool> {
        self.triangle_id
            .iter()
            .map(|&t| t == BACKGROUND_ID)
            .collect()
    }
}

/// One rendered hemicube face.
#[derive(Clone, Debug, PartialEq)]
pub struct HemicubeFaceBuffer {
    /// Which face.
    pub face: HemicubeFace,
    /// Its view.
    pub view: View,
    /// Its G-buffer.
    pub gbuffer: GBuffer,
}

/// The five views of a hemicube at `point` with `normal`, in [`HemicubeFace::ALL`] order
/// (scene-core's [`View::hemicube`]; face sizes are [`HemicubeFace::size`]: `res x res` and
/// `res x ceil(res/2)`, the side faces' image "up" being the normal, their bottom row on
/// the tangent plane).
pub fn hemicube_views(point: Vec3, normal: Vec3, near: f32, far: f32) -> [(HemicubeFace, View); 5] {
    HemicubeFace::ALL.map(|face| (face, View::hemicube(point, normal, face, near, far)))
}

/// Checks the placement of a hemicube: finite point, finite non-zero normal, resolution
/// at least 1.
pub fn check_hemicube(point: Vec3, normal: Vec3, resolution: u32) -> Result<(), Error> {
    if !(normal.is_finite() && normal.length() > 0.0 && point.is_finite()) {
        return Err(Error::InvalidArgument(format!(
            "hemicube at {point} needs a finite point and a finite non-zero normal (got {normal})"
        )));
    }
    if resolution == 0 {
        return Err(Error::InvalidArgument(
            "hemicube resolution must be at least 1".into(),
        ));
    }
    Ok(())
}

/// Something that renders a [`Scene`] seen from a [`View`] into a [`GBuffer`]. The `gbuffer`
/// crate implements it on the CPU and the GPU; `ibrr-ldc` and `relight-pr` take any
/// implementation for their hemicube renders ([`GBufferRenderer::render_hemicube`]).
pub trait GBufferRenderer {
    /// A short name for reports ("cpu", "gpu").
    fn name(&self) -> &str;
    /// Renders `scene` from `view` at `width x height`.
    fn render(
        &mut self,
        scene: &Scene,
        view: &View,
        width: u32,
        height: u32,
    ) -> Result<GBuffer, Error>;

    /// Renders the five faces of the hemicube of `resolution` at `point` with `normal`
    /// ([`hemicube_views`]), in [`HemicubeFace::ALL`] order. The default renders the faces
    /// one after the other with [`GBufferRenderer::render`]; a renderer that can batch
    /// them overrides it (the GPU rasteriser records all five into one submission).
    ///
    /// Errors on a zero resolution, a zero or non-finite normal or point
    /// ([`check_hemicube`]), and whatever the renderer reports.
    #[allow(clippy::too_many_arguments)]
    fn render_hemicube(
        &mut self,
        scene: &Scene,
        point: Vec3,
        normal: Vec3,
        resolution: u32,
        near: f32,
        far: f32,
    ) -> Result<Vec<HemicubeFaceBuffer>, Error> {
        check_hemicube(point, normal, resolution)?;
        hemicube_views(point, normal, near, far)
            .into_iter()
            .map(|(face, view)| {
                let (w, h) = face.size(resolution);
                Ok(HemicubeFaceBuffer {
                    face,
                    view,
                    gbuffer: self.render(scene, &view, w, h)?,
                })
            })
            .collect()
    }
}

/// A [`GBufferRenderer`] that casts one primary ray through each pixel centre with the
/// scene's BVH: the slow, simple reference that rasterisers are tested against, and a way
/// for any crate's tests to get a G-buffer without a rasteriser. Normals are interpolated
/// and flipped to face the viewer (two-sided surfaces); albedo includes the texture.
#[derive(Debug, Default, Clone, Copy)]
pub struct RayCastRenderer;

impl GBufferRenderer for RayCastRenderer {
    fn name(&self) -> &str {
        "raycast"
    }

    fn render(
        &mut self,
        scene: &Scene,
        view: &View,
        width: u32,
        height: u32,
    ) -> Result<GBuffer, Error> {
        use glam::Vec2;
        use rayon::prelude::*;
        let rays = crate::ray::RayScene::build(scene);
        let offsets = scene.mesh_offsets();
        let mut g = GBuffer::background(width, height);
        let w = width.max(1) as usize;
        let rows: Vec<Vec<(Vec4, Vec3, f32, u32)>> = (0..height as usize)
            .into_par_iter()
            .map(|y| {
                (0..width as usize)
                    .map(|x| {
                        let uv = Vec2::new(
                            (x as f32 + 0.5) / width as f32,
                            (y as f32 + 0.5) / height as f32,
                        );
                        let (o, d) = view.ray(uv);
                        let t_min = match view.projection {
                            crate::view::Projection::Perspective { .. } => {
                                view.near / d.dot(view.forward).max(1e-6)
                            }
                            crate::view::Projection::Orthographic { .. } => view.near,
                        };
                        let background = (Vec4::ZERO, Vec3::ZERO, 1.0, BACKGROUND_ID);
                        let Some(hit) = rays.closest_hit(o, d, t_min, f32::INFINITY) else {
                            return background;
                        };
                        let p = o + d * hit.t;
                        let depth = view.linear_depth(p);
                        if depth > 1.0 {
                            return background;
                        }
                        let Some(r) = scene.triangle_ref(&offsets, hit.triangle) else {
                            return background;
                        };
                        let mesh = &scene.meshes[r.mesh as usize];
                        let tri = mesh.indices[r.local as usize];
                        let (b1, b2) = (hit.barycentric.x, hit.barycentric.y);
                        let b = [1.0 - b1 - b2, b1, b2];
                        let pos = tri.map(|i| mesh.positions[i as usize]);
                        let ng = (pos[1] - pos[0]).cross(pos[2] - pos[0]).normalize_or_zero();
                        let mut n = (0..3)
                            .map(|k| {
                                mesh.normals.get(tri[k] as usize).copied().unwrap_or(ng) * b[k]
                            })
                            .sum::<Vec3>()
                            .normalize_or_zero();
                        if n == Vec3::ZERO {
                            n = ng;
                        }
                        if ng.dot(d) > 0.0 {
                            n = -n;
                        }
                        let uv = mesh
                            .uvs
                            .as_ref()
                            .map(|uvs| (0..3).map(|k| uvs[tri[k] as usize] * b[k]).sum::<Vec2>());
                        let material = mesh.material_ids[r.local as usize];
                        let albedo = scene.albedo_at(material, uv);
                        (albedo.extend(1.0), n, depth, hit.triangle)
                    })
                    .collect()
            })
            .collect();
        for (y, row) in rows.into_iter().enumerate() {
            for (x, (a, n, z, id)) in row.into_iter().enumerate() {
                let i = y * w + x;
                g.albedo[i] = a;
                g.normal[i] = n;
                g.depth[i] = z;
                g.triangle_id[i] = id;
            }
        }
        Ok(g)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raycast_gbuffer_of_the_cornell_box() {
        let scene = crate::builtin::scene("cornell").unwrap();
        let view = View::from_camera(&scene.cameras[0]);
        let g = RayCastRenderer.render(&scene, &view, 32, 32).unwrap();
        // The published camera sees the box interior everywhere but at the open front edge.
        let bg = g.background_mask().iter().filter(|&&b| b).count();
        assert!(bg < 32 * 4, "{bg} background pixels");
        for i in 0..g.len() {
            if g.is_background(i) {
                continue;
            }
            // Normals face the viewer and are unit; depth is inside (near/far, 1].
            let p = view.reconstruct_world(
                glam::Vec2::new(
                    ((i % 32) as f32 + 0.5) / 32.0,
                    ((i / 32) as f32 + 0.5) / 32.0,
                ),
                g.depth[i],
            );
            assert!((g.normal[i].length() - 1.0).abs() < 1e-4);
            assert!(g.normal[i].dot(view.eye - p) > 0.0);
            assert!(g.depth[i] > view.near / view.far && g.depth[i] <= 1.0);
            assert_eq!(g.albedo[i].w, 1.0);
        }
        // Every reconstructed point lies on the plane of the triangle its id names, and the
        // albedo is that triangle's material's.
        let offsets = scene.mesh_offsets();
        for i in (0..g.len()).filter(|&i| !g.is_background(i)) {
            let uv = glam::Vec2::new(
                ((i % 32) as f32 + 0.5) / 32.0,
                ((i / 32) as f32 + 0.5) / 32.0,
            );
            let p = view.reconstruct_world(uv, g.depth[i]);
            let r = scene.triangle_ref(&offsets, g.triangle_id[i]).unwrap();
            let mesh = &scene.meshes[r.mesh as usize];
            let t = mesh.indices[r.local as usize].map(|k| mesh.positions[k as usize]);
            let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
            assert!(
                n.dot(p - t[0]).abs() < 1e-4,
                "pixel {i}: {p} off its triangle"
            );
            let m = mesh.material_ids[r.local as usize] as usize;
            assert_eq!(g.albedo[i].truncate(), scene.materials[m].albedo);
        }
    }
}
