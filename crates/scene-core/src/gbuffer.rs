//! The G-buffer, the project's currency (thesis figure 4.1), and the trait of renderers
//! that produce it.

use glam::{Vec3, Vec4};

use crate::Error;
use crate::scene::Scene;
use crate::view::View;

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

/// Something that renders a [`Scene`] seen from a [`View`] into a [`GBuffer`]. The `gbuffer`
/// crate implements it on the CPU and the GPU; `ibrr-ldc` and `relight-pr` take any
/// implementation for their hemicube renders.
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
}
