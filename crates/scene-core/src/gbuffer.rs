//! The G-buffer, the project's currency (thesis figure 4.1), and the trait of renderers
//! that produce it.

use std::sync::Arc;

use glam::{Vec3, Vec4};

use crate::Error;
use crate::scene::Scene;
use crate::view::{HemicubeFace, View};

pub mod downsample;
#[cfg(feature = "rays")]
mod raycast;

pub use downsample::{DownsampleMode, coarse_size, downsample};
#[cfg(feature = "rays")]
pub use raycast::RayCastRenderer;

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

    /// Per pixel, whether its triangle (in `scene`, the scene this G-buffer was rendered
    /// of) has an emissive material: the pixels whose glow comes from the triangle id.
    pub fn emitter_mask(&self, scene: &Scene) -> Vec<bool> {
        let offsets = scene.mesh_offsets();
        self.triangle_id
            .iter()
            .map(|&id| {
                id != BACKGROUND_ID
                    && scene.triangle_ref(&offsets, id).is_some_and(|r| {
                        let m = scene.meshes[r.mesh as usize].material_ids[r.local as usize];
                        scene
                            .materials
                            .get(m as usize)
                            .is_some_and(|m| m.is_emissive())
                    })
            })
            .collect()
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

/// One view to render and the size of its image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewTarget {
    /// Where from.
    pub view: View,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl ViewTarget {
    /// `view` at `width x height`.
    pub fn new(view: View, width: u32, height: u32) -> Self {
        Self {
            view,
            width,
            height,
        }
    }
}

/// Something that renders a [`Scene`] seen from [`View`]s into [`GBuffer`]s. The `gbuffer`
/// crate implements it on the CPU and the GPU; `ibrr-ldc` and `relight-pr` take any
/// implementation for their hemicube renders ([`GBufferRenderer::render_hemicube`]).
///
/// A renderer is prepared once for a scene ([`GBufferRenderer::prepare`]: the GPU one
/// uploads it, the ray caster builds its BVH) and then renders batches of views of it
/// ([`GBufferRenderer::render_views`]) with no per-frame work on the scene: nothing is
/// hashed or uploaded again. A renderer draws whatever triangles it is given, and the
/// triangle ids it writes are that scene's ([`Scene::mesh_offsets`]): a method that meshes
/// the scene into elements prepares the renderer with the meshed scene and reads element
/// ids back.
///
/// ```
/// use std::sync::Arc;
/// use scene_core::{builtin, GBufferRenderer, View, ViewTarget, gbuffer::RayCastRenderer};
///
/// let scene = Arc::new(builtin::scene("cornell").unwrap());
/// let mut renderer = RayCastRenderer::default();
/// renderer.prepare(scene.clone()).unwrap();
/// let view = View::from_camera(&scene.cameras[0]);
/// let g = renderer.render_views(&[ViewTarget::new(view, 16, 16), ViewTarget::new(view, 8, 8)]).unwrap();
/// assert_eq!((g[0].len(), g[1].len()), (256, 64));
/// ```
pub trait GBufferRenderer {
    /// A short name for reports ("cpu", "gpu").
    fn name(&self) -> &str;

    /// Takes the scene to draw from now on (uploads it, builds acceleration structures),
    /// replacing the one prepared before.
    fn prepare(&mut self, scene: Arc<Scene>) -> Result<(), Error>;

    /// The scene prepared last, if any.
    fn prepared_scene(&self) -> Option<&Arc<Scene>>;

    /// Renders every view of `views` of the prepared scene (a renderer that can batch them
    /// records them into one submission). Errors with [`Error::NotPrepared`] before
    /// [`GBufferRenderer::prepare`], on a zero-size target, and on whatever the renderer
    /// reports.
    fn render_views(&mut self, views: &[ViewTarget]) -> Result<Vec<GBuffer>, Error>;

    /// Renders one view of the prepared scene.
    fn render_view(&mut self, view: &View, width: u32, height: u32) -> Result<GBuffer, Error> {
        self.render_views(&[ViewTarget::new(*view, width, height)])?
            .pop()
            .ok_or_else(|| Error::InvalidArgument(format!("{} rendered no view", self.name())))
    }

    /// A one-off render of `scene` from `view` at `width x height`. When `scene` is not the
    /// prepared scene this prepares a copy of it first (the CPU renderers override it to
    /// draw `scene` directly); for many views of one scene use [`GBufferRenderer::prepare`]
    /// and [`GBufferRenderer::render_views`].
    fn render(
        &mut self,
        scene: &Scene,
        view: &View,
        width: u32,
        height: u32,
    ) -> Result<GBuffer, Error> {
        let same = self
            .prepared_scene()
            .is_some_and(|s| std::ptr::eq(Arc::as_ptr(s), scene));
        if !same {
            self.prepare(Arc::new(scene.clone()))?;
        }
        self.render_view(view, width, height)
    }

    /// Renders the five faces of the hemicube of `resolution` at `point` with `normal`
    /// ([`hemicube_views`]) of the prepared scene, in [`HemicubeFace::ALL`] order, as one
    /// batch ([`GBufferRenderer::render_views`]: one submission on the GPU).
    ///
    /// Errors on a zero resolution, a zero or non-finite normal or point
    /// ([`check_hemicube`]), and whatever the renderer reports.
    fn render_hemicube(
        &mut self,
        point: Vec3,
        normal: Vec3,
        resolution: u32,
        near: f32,
        far: f32,
    ) -> Result<Vec<HemicubeFaceBuffer>, Error> {
        check_hemicube(point, normal, resolution)?;
        let faces = hemicube_views(point, normal, near, far);
        let targets: Vec<ViewTarget> = faces
            .iter()
            .map(|(face, view)| {
                let (w, h) = face.size(resolution);
                ViewTarget::new(*view, w, h)
            })
            .collect();
        let buffers = self.render_views(&targets)?;
        Ok(faces
            .into_iter()
            .zip(buffers)
            .map(|((face, view), gbuffer)| HemicubeFaceBuffer {
                face,
                view,
                gbuffer,
            })
            .collect())
    }

    /// Renders `views` of the prepared scene into G-buffers that stay on the GPU (no
    /// readback), for renderers that can; `Ok(None)` for those that cannot (the default).
    #[cfg(feature = "gpu")]
    fn render_views_gpu(
        &mut self,
        views: &[ViewTarget],
    ) -> Result<Option<Vec<crate::gpu::GpuGBuffer>>, Error> {
        let _ = views;
        Ok(None)
    }
}

/// Checks a render target's size: non-zero on both sides.
pub fn check_target_size(width: u32, height: u32) -> Result<(), Error> {
    if width == 0 || height == 0 {
        return Err(Error::InvalidArgument(format!(
            "G-buffer size {width}x{height}: zero-size targets are not allowed"
        )));
    }
    Ok(())
}

#[cfg(all(test, feature = "rays"))]
mod tests {
    use super::*;

    /// The Cornell box from its camera at 32 x 32 by the ray caster.
    fn cornell_32() -> (crate::Scene, View, GBuffer) {
        let scene = crate::builtin::scene("cornell").unwrap();
        let view = View::from_camera(&scene.cameras[0]);
        let g = RayCastRenderer::new()
            .render(&scene, &view, 32, 32)
            .unwrap();
        (scene, view, g)
    }

    #[test]
    fn raycast_gbuffer_of_the_cornell_box() {
        let (scene, view, g) = cornell_32();
        // The published camera sees the box interior everywhere but at the open front edge.
        let bg = g.background_mask().iter().filter(|&&b| b).count();
        assert!(bg < 32 * 4, "{bg} background pixels");
        for i in 0..g.len() {
            if g.is_background(i) {
                continue;
            }
            // Normals face the viewer and are unit; depth is inside (near/far, 1].
            let p = view.reconstruct_world(
                crate::view::pixel_uv(i as u32 % 32, i as u32 / 32, 32, 32),
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
            let uv = crate::view::pixel_uv(i as u32 % 32, i as u32 / 32, 32, 32);
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

    #[test]
    fn the_emitter_mask_marks_the_ceiling_panel_only() {
        let (scene, _, g) = cornell_32();
        let mask = g.emitter_mask(&scene);
        let panel = mask.iter().filter(|&&e| e).count();
        assert!(panel > 0 && panel < g.len() / 10, "{panel} panel pixels");
        // A marked pixel reconstructs onto the panel's plane, just under the ceiling, and
        // faces down; background is never marked.
        for i in (0..g.len()).filter(|&i| mask[i]) {
            assert!(!g.is_background(i));
            assert!(g.normal[i].y < -0.99, "pixel {i}: normal {}", g.normal[i]);
        }
        let lit: usize = (0..g.len())
            .filter(|&i| !mask[i] && !g.is_background(i))
            .count();
        assert!(lit > g.len() / 2);
    }
}
