//! Hemicube G-buffers: the five faces at a surface point (a full front face looking along
//! the normal and four half side faces), as `ibrr-ldc` and `relight-pr` need them, from any
//! [`GBufferRenderer`]. The views are scene-core's [`View::hemicube`]; face sizes are
//! [`HemicubeFace::size`] (`res x res` and `res x ceil(res/2)`, the side faces' image "up"
//! being the normal, their bottom row on the tangent plane).
//!
//! For the GPU renderer without readback see [`GpuRasterizer::render_hemicube_gpu`], which
//! records all five faces into one submission.
//!
//! [`GpuRasterizer::render_hemicube_gpu`]: crate::GpuRasterizer::render_hemicube_gpu

use glam::Vec3;
use scene_core::{Error, GBuffer, GBufferRenderer, HemicubeFace, Scene, View};

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

/// The five views of a hemicube at `point` with `normal`, in [`HemicubeFace::ALL`] order.
pub fn hemicube_views(point: Vec3, normal: Vec3, near: f32, far: f32) -> [(HemicubeFace, View); 5] {
    HemicubeFace::ALL.map(|face| (face, View::hemicube(point, normal, face, near, far)))
}

/// Renders the five faces of the hemicube of `resolution` at `point` with `normal`.
///
/// Errors on a zero resolution, a zero or non-finite normal, and whatever the renderer
/// reports.
#[allow(clippy::too_many_arguments)]
pub fn render_hemicube<R: GBufferRenderer + ?Sized>(
    renderer: &mut R,
    scene: &Scene,
    point: Vec3,
    normal: Vec3,
    resolution: u32,
    near: f32,
    far: f32,
) -> Result<Vec<HemicubeFaceBuffer>, Error> {
    if !(normal.is_finite() && normal.length() > 0.0 && point.is_finite()) {
        return Err(Error::InvalidArgument(format!(
            "hemicube at {point} needs a finite non-zero normal (got {normal})"
        )));
    }
    hemicube_views(point, normal, near, far)
        .into_iter()
        .map(|(face, view)| {
            let (w, h) = face.size(resolution);
            Ok(HemicubeFaceBuffer {
                face,
                view,
                gbuffer: renderer.render(scene, &view, w, h)?,
            })
        })
        .collect()
}
