//! The ray-cast G-buffer renderer (feature `rays`): one primary ray per pixel centre through
//! the scene's BVH.

use std::sync::Arc;

use glam::{Vec3, Vec4};

use super::{BACKGROUND_ID, GBuffer, GBufferRenderer, ViewTarget, check_target_size};
use crate::Error;
use crate::scene::Scene;
use crate::view::View;

/// A [`GBufferRenderer`] that casts one primary ray through each pixel centre with the
/// scene's BVH: the slow, simple reference that rasterisers are tested against, and a way
/// for any crate's tests to get a G-buffer without a rasteriser. Normals are interpolated
/// and flipped to face the viewer (two-sided surfaces); albedo includes the texture.
/// [`GBufferRenderer::prepare`] builds the BVH once; the one-off
/// [`GBufferRenderer::render`] builds it for that call.
#[derive(Default)]
pub struct RayCastRenderer {
    prepared: Option<(Arc<Scene>, crate::ray::RayScene, Vec<u32>)>,
}

impl std::fmt::Debug for RayCastRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RayCastRenderer")
            .field("prepared", &self.prepared.as_ref().map(|p| &p.0.name))
            .finish()
    }
}

impl RayCastRenderer {
    /// A renderer with no scene prepared.
    pub fn new() -> Self {
        Self::default()
    }
}

impl GBufferRenderer for RayCastRenderer {
    fn name(&self) -> &str {
        "raycast"
    }

    fn prepare(&mut self, scene: Arc<Scene>) -> Result<(), Error> {
        let rays = crate::ray::RayScene::build(&scene);
        let offsets = scene.mesh_offsets();
        self.prepared = Some((scene, rays, offsets));
        Ok(())
    }

    fn prepared_scene(&self) -> Option<&Arc<Scene>> {
        self.prepared.as_ref().map(|p| &p.0)
    }

    fn render_views(&mut self, views: &[ViewTarget]) -> Result<Vec<GBuffer>, Error> {
        let Some((scene, rays, offsets)) = self.prepared.as_ref() else {
            return Err(Error::NotPrepared("the ray-cast G-buffer renderer".into()));
        };
        views
            .iter()
            .map(|t| raycast(scene, rays, offsets, &t.view, t.width, t.height))
            .collect()
    }

    fn render(
        &mut self,
        scene: &Scene,
        view: &View,
        width: u32,
        height: u32,
    ) -> Result<GBuffer, Error> {
        if let Some((s, rays, offsets)) = self.prepared.as_ref()
            && std::ptr::eq(Arc::as_ptr(s), scene)
        {
            return raycast(s, rays, offsets, view, width, height);
        }
        let rays = crate::ray::RayScene::build(scene);
        raycast(scene, &rays, &scene.mesh_offsets(), view, width, height)
    }
}

/// One primary ray per pixel centre of `view` through `rays` (built from `scene`).
fn raycast(
    scene: &Scene,
    rays: &crate::ray::RayScene,
    offsets: &[u32],
    view: &View,
    width: u32,
    height: u32,
) -> Result<GBuffer, Error> {
    use glam::Vec2;
    use rayon::prelude::*;
    check_target_size(width, height)?;
    let mut g = GBuffer::background(width, height);
    let w = width as usize;
    let rows: Vec<Vec<(Vec4, Vec3, f32, u32)>> = (0..height as usize)
        .into_par_iter()
        .map(|y| {
            (0..w)
                .map(|x| {
                    let uv = crate::view::pixel_uv(x as u32, y as u32, width, height);
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
                    let Some(r) = scene.triangle_ref(offsets, hit.triangle) else {
                        return background;
                    };
                    let mesh = &scene.meshes[r.mesh as usize];
                    let tri = mesh.indices[r.local as usize];
                    let (b1, b2) = (hit.barycentric.x, hit.barycentric.y);
                    let b = [1.0 - b1 - b2, b1, b2];
                    let pos = tri.map(|i| mesh.positions[i as usize]);
                    let ng = (pos[1] - pos[0]).cross(pos[2] - pos[0]).normalize_or_zero();
                    let mut n = (0..3)
                        .map(|k| mesh.normals.get(tri[k] as usize).copied().unwrap_or(ng) * b[k])
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
                    let albedo = scene.albedo_at(material, uv) * mesh.color_at(r.local as usize, b);
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
