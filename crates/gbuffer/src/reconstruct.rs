//! World- and view-space positions from a G-buffer's depth (thesis section 4.3), on the
//! CPU and in WGSL (`shaders/gbuffer/reconstruct.wgsl`, [`RECONSTRUCT`]).
//!
//! * [`FrustumReconstruction`]: the thesis' method (eqs. 23-24). The G-buffer stores linear
//!   depth `d` = view distance along the view direction / far; the position seen at image
//!   coordinates `(u, v)` is `eye + (f_o + u f_u + v f_v) d`, with `f_o` the vector from the
//!   eye to the far plane's top-left corner and `f_u`, `f_v` the far plane's edges. Six
//!   multiply-adds per position; exact up to rounding. Orthographic views (shadow maps)
//!   take the same affine form with the roles swapped: the base point moves with `(u, v)`
//!   and the depth direction is constant.
//! * [`InverseMatrixReconstruction`]: the comparison method, a 4x4 matrix product and a
//!   division per position. From linear depth it inverts a linear-depth clip transform
//!   (well conditioned); from the hardware depth buffer (`z_ndc`, what the thesis compared
//!   against) it is `M^-1 (x_ndc, y_ndc, z_ndc, 1)` divided by `w`, which inherits the
//!   hyperbolic depth buffer's loss of precision far from the eye.
//!
//! [`reconstruct_buffer`] and [`GpuReconstructor`] reconstruct whole buffers with several
//! taps per pixel, for the micro-benchmark in `cargo xtask bench gbuffer`.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec2, Vec3, Vec4};
use rayon::prelude::*;
use scene_core::View;
use scene_core::gpu::shader::ShaderPass;
use scene_core::gpu::{ComputePass, GpuContext, GpuError, GpuGBuffer};
use scene_core::view::Projection;

/// The reconstruction passes (`shaders/gbuffer/reconstruct.wgsl`, one entry point per
/// method, importing `scene_core::reconstruct`).
pub const RECONSTRUCT: ShaderPass = ShaderPass::new(
    "gbuffer/reconstruct",
    scene_core::wgsl_file!("gbuffer", "reconstruct.wgsl"),
    &[scene_core::gpu::shader::RECONSTRUCT],
);

pub use scene_core::view::FrustumReconstruction;

/// Reconstruction by inverse matrices, for comparison.
///
/// From linear depth it uses the inverse of a *linear-depth clip transform* `L V` (view
/// matrix `V`, then `L` mapping a view-space point to `(x_c, y_c, 1, d)` for perspective
/// views, `x_c`, `y_c` the usual clip coordinates and `d` the linear depth, or to
/// `(x_ndc, y_ndc, d, 1)` for orthographic ones). The input vector is rebuilt from
/// `(u, v, d)` as `(x_ndc a, y_ndc a, b, c)` with `a`, `b`, `c` affine in `d`
/// ([`InverseMatrixReconstruction::lin`]), multiplied by `(L V)^-1` and divided by `w`:
/// the cost of the textbook method without its precision problem. The textbook route
/// through the standard projection's clip `z` cancels catastrophically when `near/far` is
/// small (an error of about `1e-7 far/near` of the distance in f32: 1.3e-4 of the depth
/// range for the built-in cameras' `near = far/1000`).
///
/// From the hardware depth buffer (`z_ndc`) it is the textbook `M^-1 (x_ndc, y_ndc, z_ndc,
/// 1)` divided by `w` with `M` the view-projection matrix, as the thesis compared.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InverseMatrixReconstruction {
    /// `(L V)^-1` (computed in f64, stored in f32).
    pub inv_linear: Mat4,
    /// `L^-1`, for view-space positions.
    pub inv_linear_view: Mat4,
    /// Inverse of the standard view-projection matrix, for `z_ndc` input.
    pub inv_view_proj: Mat4,
    /// Coefficients of the input vector: `a = lin[0] + lin[1] d`, `b = lin[2] + lin[3] d`,
    /// `c = lin[4] + lin[5] d` (perspective `(0, far, 1, 0, 0, 1)`, orthographic
    /// `(1, 0, 0, 1, 1, 0)`).
    pub lin: [f32; 6],
    /// `(P[2].z, P[3].z, P[2].w, P[3].w)` of the projection matrix `P` (columns): view
    /// z to clip z and w, for converting linear depth to `z_ndc`.
    pub proj_zw: Vec4,
    /// The far plane distance.
    pub far: f32,
}

impl InverseMatrixReconstruction {
    /// The matrices of `view`.
    pub fn new(view: &View) -> Self {
        let p = view.projection_matrix().as_dmat4();
        let v = view.view_matrix().as_dmat4();
        let far = view.far as f64;
        // Rows of L (glam matrices are built from columns: transpose the row form).
        let (rows, lin) = match view.projection {
            Projection::Perspective { .. } => (
                [
                    [p.x_axis.x, p.y_axis.x, p.z_axis.x, 0.0],
                    [p.x_axis.y, p.y_axis.y, p.z_axis.y, 0.0],
                    [0.0, 0.0, 0.0, 1.0],
                    [0.0, 0.0, -1.0 / far, 0.0],
                ],
                [0.0, view.far, 1.0, 0.0, 0.0, 1.0],
            ),
            Projection::Orthographic { .. } => (
                [
                    [p.x_axis.x, p.y_axis.x, p.z_axis.x, p.w_axis.x],
                    [p.x_axis.y, p.y_axis.y, p.z_axis.y, p.w_axis.y],
                    [0.0, 0.0, -1.0 / far, 0.0],
                    [0.0, 0.0, 0.0, 1.0],
                ],
                [1.0, 0.0, 0.0, 1.0, 1.0, 0.0],
            ),
        };
        let l = glam::DMat4::from_cols_array_2d(&rows).transpose();
        let pf = view.projection_matrix();
        Self {
            inv_linear: (l * v).inverse().as_mat4(),
            inv_linear_view: l.inverse().as_mat4(),
            inv_view_proj: (p * v).inverse().as_mat4(),
            lin,
            proj_zw: Vec4::new(pf.z_axis.z, pf.w_axis.z, pf.z_axis.w, pf.w_axis.w),
            far: view.far,
        }
    }

    /// The input vector `(x_ndc a, y_ndc a, b, c)` for image coordinates `uv` and linear
    /// depth `depth`.
    #[inline]
    pub fn linear_clip_point(&self, uv: Vec2, depth: f32) -> Vec4 {
        let l = &self.lin;
        let a = l[0] + l[1] * depth;
        let ndc = Vec2::new(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
        Vec4::new(
            ndc.x * a,
            ndc.y * a,
            l[2] + l[3] * depth,
            l[4] + l[5] * depth,
        )
    }

    /// World-space position from linear depth.
    #[inline]
    pub fn world(&self, uv: Vec2, depth: f32) -> Vec3 {
        let p = self.inv_linear * self.linear_clip_point(uv, depth);
        p.truncate() / p.w
    }

    /// View-space position from linear depth.
    #[inline]
    pub fn view_space(&self, uv: Vec2, depth: f32) -> Vec3 {
        let p = self.inv_linear_view * self.linear_clip_point(uv, depth);
        p.truncate() / p.w
    }

    /// The hardware depth buffer value (`z_ndc` in [0, 1]) of linear depth `depth`.
    #[inline]
    pub fn ndc_depth(&self, depth: f32) -> f32 {
        let zv = -depth * self.far;
        (self.proj_zw.x * zv + self.proj_zw.y) / (self.proj_zw.z * zv + self.proj_zw.w)
    }

    /// World-space position from the hardware depth buffer value `z_ndc` (the thesis'
    /// "multiply the screen-space vector by the inverse matrix and divide by w").
    #[inline]
    pub fn world_from_ndc(&self, uv: Vec2, z_ndc: f32) -> Vec3 {
        let p = self.inv_view_proj * Vec4::new(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, z_ndc, 1.0);
        p.truncate() / p.w
    }
}

/// Which reconstruction [`reconstruct_buffer`] and [`GpuReconstructor`] use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ReconstructionMethod {
    /// Eqs. 23-24 from linear depth.
    FrustumCorners,
    /// Inverse view-projection matrix from linear depth.
    InverseMatrix,
    /// Inverse view-projection matrix from the hardware depth buffer (`z_ndc`).
    InverseMatrixHardwareDepth,
}

impl ReconstructionMethod {
    /// All methods.
    pub const ALL: [ReconstructionMethod; 3] = [
        ReconstructionMethod::FrustumCorners,
        ReconstructionMethod::InverseMatrix,
        ReconstructionMethod::InverseMatrixHardwareDepth,
    ];

    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            ReconstructionMethod::FrustumCorners => "frustum corners (eq. 24)",
            ReconstructionMethod::InverseMatrix => "inverse matrix, linear depth",
            ReconstructionMethod::InverseMatrixHardwareDepth => "inverse matrix, z-buffer",
        }
    }

    fn entry_point(self) -> &'static str {
        match self {
            ReconstructionMethod::FrustumCorners => "frustum_main",
            ReconstructionMethod::InverseMatrix => "inverse_main",
            ReconstructionMethod::InverseMatrixHardwareDepth => "inverse_hw_main",
        }
    }
}

/// Largest tap count of [`reconstruct_buffer`] and [`GpuReconstructor`].
pub const MAX_TAPS: u32 = 24;

/// The tap pattern (pixel offsets; the first is the pixel itself), as in the shader.
pub const TAP_OFFSETS: [[i32; 2]; MAX_TAPS as usize] = [
    [0, 0],
    [1, 0],
    [0, 1],
    [-1, 0],
    [0, -1],
    [2, 1],
    [-1, 2],
    [-2, -1],
    [1, -2],
    [3, 0],
    [0, 3],
    [-3, 0],
    [0, -3],
    [2, 3],
    [-3, 2],
    [-2, -3],
    [3, -2],
    [4, 1],
    [-1, 4],
    [-4, -1],
    [1, -4],
    [4, 4],
    [-4, 4],
    [4, -4],
];

/// Reconstructs, for every pixel of a `width x height` depth buffer, the mean world
/// position of `taps` (1..=24) pixels around it (the CPU twin of [`GpuReconstructor`];
/// rayon over rows). `depth` is linear depth, or the hardware `z_ndc` for
/// [`ReconstructionMethod::InverseMatrixHardwareDepth`]. With `taps == 1` each output is
/// the pixel's own position.
///
/// Panics if `depth.len() != width * height`.
pub fn reconstruct_buffer(
    view: &View,
    method: ReconstructionMethod,
    depth: &[f32],
    width: u32,
    height: u32,
    taps: u32,
) -> Vec<Vec3> {
    let mut out = vec![Vec3::ZERO; width as usize * height as usize];
    reconstruct_into(view, method, depth, width, height, taps, &mut out);
    out
}

/// [`reconstruct_buffer`] into an existing slice (no allocation; for benchmarks).
///
/// Panics if `depth` or `out` does not have `width * height` elements.
pub fn reconstruct_into(
    view: &View,
    method: ReconstructionMethod,
    depth: &[f32],
    width: u32,
    height: u32,
    taps: u32,
    out: &mut [Vec3],
) {
    let (w, h) = (width as usize, height as usize);
    assert_eq!(depth.len(), w * h, "depth buffer size");
    assert_eq!(out.len(), w * h, "output size");
    if out.is_empty() {
        return;
    }
    let n = taps.clamp(1, MAX_TAPS) as usize;
    let frustum = FrustumReconstruction::new(view);
    let inverse = InverseMatrixReconstruction::new(view);
    let size = Vec2::new(width as f32, height as f32);
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let mut sum = Vec3::ZERO;
            for off in &TAP_OFFSETS[..n] {
                let px = (x as i32 + off[0]).clamp(0, w as i32 - 1);
                let py = (y as i32 + off[1]).clamp(0, h as i32 - 1);
                let uv = (Vec2::new(px as f32, py as f32) + 0.5) / size;
                let d = depth[py as usize * w + px as usize];
                sum += match method {
                    ReconstructionMethod::FrustumCorners => frustum.world(uv, d),
                    ReconstructionMethod::InverseMatrix => inverse.world(uv, d),
                    ReconstructionMethod::InverseMatrixHardwareDepth => {
                        inverse.world_from_ndc(uv, d)
                    }
                };
            }
            *o = sum / n as f32;
        }
    });
}

/// The uniform of `reconstruct.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct Params {
    frustum: [[f32; 4]; 6],
    inv_linear: [f32; 16],
    inv_view_proj: [f32; 16],
    lin_a: [f32; 4],
    lin_c: [f32; 2],
    taps: u32,
    pad: u32,
}

/// The WGSL reconstruction passes: one module, one compute pass per method (scene-core's
/// [`ComputePass`]).
#[derive(Debug)]
pub struct GpuReconstructor {
    ctx: GpuContext,
    passes: [ComputePass; 3],
}

impl GpuReconstructor {
    /// Compiles the three pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let device = &ctx.device;
        let module = RECONSTRUCT.create_module(device)?;
        let passes = ctx.validated(|| {
            use scene_core::gpu::layout::{float_texture, storage_texture, texture, uniform};
            let entries = [
                float_texture(0),
                texture(1, wgpu::TextureSampleType::Depth),
                storage_texture(2, wgpu::TextureFormat::Rgba32Float),
                uniform(3),
            ];
            ReconstructionMethod::ALL.map(|m| {
                ComputePass::from_entry_point(
                    device,
                    m.entry_point(),
                    &module,
                    m.entry_point(),
                    &entries,
                    &[],
                )
            })
        })?;
        Ok(Self {
            ctx: ctx.clone(),
            passes,
        })
    }

    /// A `width x height` `Rgba32Float` output texture (storage and copy source).
    pub fn output_texture(&self, width: u32, height: u32) -> Result<wgpu::Texture, GpuError> {
        self.ctx.check_texture_size(width, height)?;
        self.ctx.validated(|| {
            self.ctx.create_texture_2d(
                "reconstructed positions",
                width,
                height,
                wgpu::TextureFormat::Rgba32Float,
                wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
            )
        })
    }

    /// Records one reconstruction pass of `gbuffer` (its linear depth, or its depth-stencil
    /// attachment for [`ReconstructionMethod::InverseMatrixHardwareDepth`]) as seen from
    /// `view` into `out` (from [`GpuReconstructor::output_texture`], same size).
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        view: &View,
        gbuffer: &GpuGBuffer,
        method: ReconstructionMethod,
        taps: u32,
        out: &wgpu::Texture,
    ) -> Result<(), GpuError> {
        if (out.width(), out.height()) != (gbuffer.width, gbuffer.height) {
            return Err(GpuError::InvalidSize {
                width: out.width(),
                height: out.height(),
                reason: format!(
                    "the output must match the G-buffer's {}x{}",
                    gbuffer.width, gbuffer.height
                ),
            });
        }
        let f = FrustumReconstruction::new(view);
        let inv = InverseMatrixReconstruction::new(view);
        let params = Params {
            frustum: f.uniform(),
            inv_linear: inv.inv_linear.to_cols_array(),
            inv_view_proj: inv.inv_view_proj.to_cols_array(),
            lin_a: [inv.lin[0], inv.lin[1], inv.lin[2], inv.lin[3]],
            lin_c: [inv.lin[4], inv.lin[5]],
            taps: taps.clamp(1, MAX_TAPS),
            pad: 0,
        };
        let device = &self.ctx.device;
        let index = ReconstructionMethod::ALL
            .iter()
            .position(|&m| m == method)
            .unwrap_or(0);
        let hw_depth = gbuffer.depth_attachment()?;
        self.ctx.validated(|| {
            let uniform = self.ctx.uniform_buffer("reconstruct params", &params);
            let linear = gbuffer.depth.create_view(&Default::default());
            let hw = hw_depth.create_view(&Default::default());
            let out_view = out.create_view(&Default::default());
            let pass = &self.passes[index];
            let bind_group = pass.bind(
                device,
                &[
                    wgpu::BindingResource::TextureView(&linear),
                    wgpu::BindingResource::TextureView(&hw),
                    wgpu::BindingResource::TextureView(&out_view),
                    uniform.as_entire_binding(),
                ],
            );
            pass.dispatch(encoder, &bind_group, gbuffer.width, gbuffer.height, None);
        })
    }

    /// Runs one pass into a new output texture, waits, and reads the positions back
    /// (row-major).
    pub fn run(
        &self,
        view: &View,
        gbuffer: &GpuGBuffer,
        method: ReconstructionMethod,
        taps: u32,
    ) -> Result<Vec<Vec3>, GpuError> {
        let out = self.output_texture(gbuffer.width, gbuffer.height)?;
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("gbuffer reconstruct"),
            });
        self.encode(&mut encoder, view, gbuffer, method, taps, &out)?;
        self.ctx
            .validated(|| self.ctx.queue.submit([encoder.finish()]))?;
        Ok(self.ctx.read_texture_image(&out)?.pixels)
    }
}

/// The uniform has the layout naga gives its WGSL twin (a field moved on one side fails
/// here).
#[cfg(test)]
mod layout_tests {
    use super::*;

    #[test]
    fn params_match_the_wgsl_struct() {
        let module = RECONSTRUCT.compose().unwrap();
        scene_core::check_layout!(
            &module,
            "Params",
            Params {
                frustum,
                inv_linear,
                inv_view_proj,
                lin_a,
                lin_c,
                taps,
                pad,
            }
        )
        .unwrap();
    }
}
