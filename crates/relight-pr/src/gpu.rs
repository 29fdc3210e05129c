//! Relighting on the GPU (wgpu compute, `shaders/relight-pr/`): eq. 1 over the packed
//! element solution ([`GpuRelight::relight`]), and the paper's "hardware" display: the
//! per-light radiosity at the welded vertices combined with the frame's light factors per
//! pixel in one pass over a G-buffer of the element scene ([`GpuRelight::display`]), with
//! the direct light from the elements, from per-pixel values the caller gathered, or from
//! scene-core's shadow-mapped lights evaluated per frame by a pass of its own
//! ([`GpuRelight::set_shadowed_direct`], [`GpuRelight::encode_display_shadowed`]). The
//! solution is uploaded once; a frame uploads only the k factor pairs.

use glam::Vec3;
use scene_core::gpu::compute::ComputePass;
use scene_core::gpu::layout::{storage_buffer, storage_buffer_rw, uniform};
use scene_core::gpu::shader::{ShaderPass, Wgsl};
use scene_core::gpu::{FrameWriter, GpuContext, GpuError, GpuGBuffer, KeptBuffer, Keyed};
use scene_core::shadowed_lights::LightSet;
use scene_core::shadowed_lights::gpu::{LIGHT_SET, SHADOW, ShadowParams, gpu_lights};
use scene_core::view::FrustumReconstruction;
use scene_core::{Image, View};

use crate::RelightError;
use crate::display::Welding;
use crate::mesh::Meshing;
use crate::packed::{Packed, Precision};
use crate::solver::Solution;

/// The packed solution and eq. 1 over it (`relight_pr::common`), which both passes import.
pub const COMMON: Wgsl = scene_core::wgsl_file!("relight-pr", "common.wgsl");

/// The relight pass (eq. 1 at every element).
pub const RELIGHT: ShaderPass = ShaderPass::new(
    "relight-pr/relight",
    scene_core::wgsl_file!("relight-pr", "relight.wgsl"),
    &[COMMON],
);

/// One row of the display's element table (`relight_pr::element`, the layout of the
/// element table this module uploads), which the display and direct passes import.
pub const ELEMENT: Wgsl = scene_core::wgsl_file!("relight-pr", "element.wgsl");

/// The display pass (eq. 1 per pixel over the welded vertices; imports
/// `scene_core::reconstruct` too).
pub const DISPLAY: ShaderPass = ShaderPass::new(
    "relight-pr/display",
    scene_core::wgsl_file!("relight-pr", "display.wgsl"),
    &[COMMON, ELEMENT, scene_core::gpu::shader::RECONSTRUCT],
);

/// The per-frame direct pass: scene-core's shadow-mapped lights at every pixel, summed per
/// source ([`crate::direct::DirectLight::ShadowMaps`]).
pub const DIRECT: ShaderPass = ShaderPass::new(
    "relight-pr/direct",
    scene_core::wgsl_file!("relight-pr", "direct.wgsl"),
    &[
        scene_core::gpu::shader::RECONSTRUCT,
        scene_core::gpu::shader::LIMITS,
        LIGHT_SET,
        SHADOW,
        ELEMENT,
    ],
);

/// Every shader pass of relighting, as `cargo xtask shaders` validates them.
pub const SHADER_PASSES: &[ShaderPass] =
    &[RELIGHT, DISPLAY, DIRECT, crate::element_ids::TRIANGLE_IDS];

const GROUP: u32 = 64;
const MAX_GROUPS_X: u32 = 32768;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct RelightParams {
    n: u32,
    k: u32,
    pad: [u32; 2],
    base: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct DisplayParams {
    frustum: [[f32; 4]; 6],
    width: u32,
    height: u32,
    k: u32,
    elements: u32,
    base: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct DirectParams {
    frustum: [[f32; 4]; 6],
    width: u32,
    height: u32,
    k: u32,
    light_count: u32,
    shadow_params: ShadowParams,
    footprint: u32,
    pad: [u32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuElement {
    a: [f32; 4],
    b: [f32; 4],
    c: [f32; 4],
    emission: [f32; 4],
    vertex: [u32; 4],
}

/// The element table of a relight-only copy: one zero element.
const EMPTY_TABLE: GpuElement = GpuElement {
    a: [0.0; 4],
    b: [0.0; 4],
    c: [0.0; 4],
    emission: [0.0; 4],
    vertex: [0; 4],
};

/// A solution resident on the GPU, ready to relight and display.
pub struct GpuRelight {
    ctx: GpuContext,
    k: usize,
    /// Solution elements (groups of mesh elements, [`Meshing::groups`]).
    elements: usize,
    /// Mesh elements in the element table (what the display's triangle ids index).
    mesh_elements: usize,
    precision: Precision,
    vertex_words: wgpu::Buffer,
    element_table: wgpu::Buffer,
    irradiance: wgpu::Buffer,
    relight_pass: ComputePass,
    display_pass: ComputePass,
    display_per_pixel: ComputePass,
    bytes: u64,
    /// A frame's parameters and factors are copied into these by commands of the frame's
    /// own encoder ([`FrameWriter`]): a steady stream of frames creates no GPU object.
    writer: FrameWriter,
    relight_params: wgpu::Buffer,
    relight_factors: wgpu::Buffer,
    relight_bind: wgpu::BindGroup,
    display_params: wgpu::Buffer,
    display_factors: wgpu::Buffer,
    /// The per-pixel direct light (grown when a frame needs more).
    direct: std::sync::Mutex<KeptBuffer>,
    /// The display's bind group and what it was made for.
    display_bind: std::sync::Mutex<Keyed<DisplayKey, wgpu::BindGroup>>,
    /// The shadow-mapped lights of the per-frame direct pass, once set.
    shadowed: Option<ShadowedDirect>,
}

/// Scene-core's shadow-mapped lights on the GPU and the pass that evaluates them per pixel
/// into the display's per-pixel direct buffer.
struct ShadowedDirect {
    pass: ComputePass,
    params: wgpu::Buffer,
    lights: wgpu::Buffer,
    texels: wgpu::Buffer,
    texel_count: usize,
    slots: wgpu::Buffer,
    count: u32,
    shadow: ShadowParams,
    footprint: u32,
    /// The pass' bind group and what it was made for: the G-buffer's normal, depth and id
    /// textures and the direct buffer's generation.
    bind: std::sync::Mutex<Keyed<DirectKey, wgpu::BindGroup>>,
}

/// What the direct pass' bind group depends on: the G-buffer's normal, depth and id
/// textures by identity and the direct buffer's generation.
type DirectKey = ([wgpu::Texture; 3], u64);

/// Where a display takes its direct light from.
#[derive(Clone, Copy)]
enum Direct<'a> {
    /// The elements (the paper's display).
    Elements,
    /// Values the caller gathered, pixel-major.
    Values(&'a [Vec3]),
    /// The shadow-mapped lights, evaluated by the direct pass in the same encoder.
    Shadowed,
}

/// What the display's bind group depends on: the G-buffer's textures and the output by
/// identity, the pass, and the direct-light buffer's generation.
#[derive(Clone, Debug, PartialEq)]
struct DisplayKey {
    textures: [wgpu::Texture; 3],
    output: wgpu::Buffer,
    per_pixel: bool,
    direct: u64,
}

impl std::fmt::Debug for GpuRelight {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuRelight")
            .field("k", &self.k)
            .field("elements", &self.elements)
            .field("precision", &self.precision)
            .field("bytes", &self.bytes)
            .finish_non_exhaustive()
    }
}

impl GpuRelight {
    /// Uploads `solution` (over `meshing`, welded by `welding`) at `precision`. Fails with
    /// [`RelightError::Budget`] before allocating when a buffer would exceed the adapter's
    /// storage-binding or buffer size, and with [`RelightError::InvalidSetting`] when f16
    /// storage would saturate a value ([`Packed::saturated`]).
    pub fn new(
        ctx: &GpuContext,
        meshing: &Meshing,
        welding: &Welding,
        solution: &Solution,
        precision: Precision,
    ) -> Result<Self, RelightError> {
        let k = solution.k();
        let n = meshing.elements.len();
        if solution.k() > 0 && solution.elements != meshing.groups.count && solution.elements != n {
            return Err(RelightError::InvalidSetting(format!(
                "a solution of {} elements for a meshing of {n} mesh elements in {} groups",
                solution.elements, meshing.groups.count
            )));
        }
        let limit = ctx.storage_binding_limit();
        let words = (solution.elements * k * precision.words()) as u64 * 4;
        let vertex_bytes = (welding.vertices * k * precision.words()) as u64 * 4;
        for (what, bytes) in [
            ("packed element solution", words),
            ("packed vertex solution", vertex_bytes),
            ("element table", n as u64 * 80),
        ] {
            check_binding(what, bytes, limit)?;
        }
        let packed = Packed::new(&solution.direct, &solution.indirect, k, precision);
        let (vd, vi) = welding.vertex_solution(meshing, solution);
        let vertex = Packed::new(&vd, &vi, k, precision);
        let saturated = packed.saturated + vertex.saturated;
        if saturated > 0 {
            return Err(RelightError::InvalidSetting(format!(
                "f16 storage would saturate {saturated} value(s) of the solution at 65504 (the \
                 scene's lights are that bright): use Precision::F32, or scale the scene's \
                 units"
            )));
        }
        let table: Vec<GpuElement> = meshing
            .elements
            .iter()
            .enumerate()
            .map(|(j, e)| {
                let source = meshing.patches[e.patch as usize]
                    .light
                    .and_then(|id| solution.source_of(id))
                    .map_or(0.0, |m| (m + 1) as f32);
                let v = |c: usize| welding.corner_vertex[3 * j + c];
                GpuElement {
                    a: e.corners[0].extend(source).to_array(),
                    b: e.corners[1].extend(0.0).to_array(),
                    c: e.corners[2].extend(0.0).to_array(),
                    emission: meshing.seen_emission(j).extend(0.0).to_array(),
                    vertex: [v(0), v(1), v(2), 0],
                }
            })
            .collect();
        Self::assemble(ctx, &packed, Some(&vertex), &table)
    }

    /// A GPU copy of `packed` for [`GpuRelight::relight`] only (no display data): what a
    /// benchmark of eq. 1 alone needs. Budget checks as [`GpuRelight::new`].
    pub fn relight_only(ctx: &GpuContext, packed: &Packed) -> Result<Self, RelightError> {
        Self::assemble(ctx, packed, None, &[])
    }

    /// Checks every buffer against the adapter's limits, then builds the passes and
    /// uploads.
    fn assemble(
        ctx: &GpuContext,
        packed: &Packed,
        vertex: Option<&Packed>,
        table: &[GpuElement],
    ) -> Result<Self, RelightError> {
        let limit = ctx.storage_binding_limit();
        let vertex_bytes = vertex.map_or(0, Packed::bytes);
        let table_bytes = std::mem::size_of_val(table) as u64;
        for (what, bytes) in [
            ("packed element solution", packed.bytes()),
            ("packed vertex solution", vertex_bytes),
            ("element table", table_bytes),
        ] {
            check_binding(what, bytes, limit)?;
        }
        let constants: &[(&str, f64)] =
            &[("F16", (packed.precision == Precision::F16) as u8 as f64)];
        let relight_pass = ComputePass::new(
            &ctx.device,
            "relight-pr relight",
            &RELIGHT,
            &[
                uniform(0),
                storage_buffer(1),
                storage_buffer(2),
                storage_buffer_rw(3),
            ],
            constants,
        )
        .map_err(gpu)?;
        let display_entries = Self::display_entries();
        let display_module = DISPLAY.create_module(&ctx.device).map_err(gpu)?;
        let display = |per_pixel: bool| {
            ComputePass::from_module(
                &ctx.device,
                "relight-pr display",
                &display_module,
                &display_entries,
                &[constants[0], ("PER_PIXEL_DIRECT", per_pixel as u8 as f64)],
            )
        };
        let (display_pass, display_per_pixel) = (display(false), display(true));
        let n = packed.n;
        let vertex_words: &[u32] = vertex.map_or(&[], |v| &v.words);
        let device = &ctx.device;
        let factor_bytes = packed.k as u64 * 32;
        let element_words = ctx.storage_with(
            "packed solution",
            bytemuck::cast_slice(&packed.words),
            wgpu::BufferUsages::empty(),
        );
        let irradiance = ctx.storage_with(
            "relit irradiance",
            &vec![0u8; n.max(1) * 16],
            wgpu::BufferUsages::COPY_SRC,
        );
        let relight_params = ctx.frame_buffer(
            "relight params",
            std::mem::size_of::<RelightParams>() as u64,
            wgpu::BufferUsages::UNIFORM,
        );
        let relight_factors =
            ctx.frame_buffer("relight factors", factor_bytes, wgpu::BufferUsages::STORAGE);
        let relight_bind = relight_pass.bind(
            device,
            &[
                relight_params.as_entire_binding(),
                element_words.as_entire_binding(),
                relight_factors.as_entire_binding(),
                irradiance.as_entire_binding(),
            ],
        );
        ctx.validated(|| Self {
            writer: FrameWriter::new(device, 4096),
            relight_params,
            relight_factors,
            relight_bind,
            display_params: ctx.frame_buffer(
                "display params",
                std::mem::size_of::<DisplayParams>() as u64,
                wgpu::BufferUsages::UNIFORM,
            ),
            display_factors: ctx.frame_buffer(
                "display factors",
                factor_bytes,
                wgpu::BufferUsages::STORAGE,
            ),
            direct: std::sync::Mutex::new(KeptBuffer::new(
                "pixel direct",
                wgpu::BufferUsages::STORAGE,
            )),
            display_bind: std::sync::Mutex::new(Keyed::new()),
            shadowed: None,
            ctx: ctx.clone(),
            k: packed.k,
            elements: n,
            mesh_elements: table.len(),
            precision: packed.precision,
            vertex_words: ctx.storage_with(
                "packed vertex solution",
                bytemuck::cast_slice(vertex_words),
                wgpu::BufferUsages::empty(),
            ),
            // At least one (zero) element: the shaders' element arrays have an 80-byte
            // stride, and a relight-only copy has no table (`mesh_elements` stays 0, so
            // no id reaches it).
            element_table: ctx.storage_with(
                "element table",
                if table.is_empty() {
                    bytemuck::bytes_of(&EMPTY_TABLE)
                } else {
                    bytemuck::cast_slice(table)
                },
                wgpu::BufferUsages::empty(),
            ),
            irradiance,
            relight_pass,
            display_pass,
            display_per_pixel,
            bytes: packed.bytes() + vertex_bytes + table_bytes + n as u64 * 16,
        })
        .map_err(gpu)
    }

    fn display_entries() -> [wgpu::BindGroupLayoutEntry; 9] {
        [
            uniform(0),
            storage_buffer(1),
            storage_buffer(2),
            storage_buffer(3),
            storage_buffer(4),
            storage_buffer_rw(5),
            scene_core::gpu::layout::float_texture(6),
            scene_core::gpu::layout::float_texture(7),
            scene_core::gpu::layout::texture(8, wgpu::TextureSampleType::Uint),
        ]
    }

    /// The time of one relight pass (eq. 1 over every element, no readback): GPU
    /// timestamps where the adapter has them, else the wall clock from submission to the
    /// device going idle.
    pub fn time_relight(
        &self,
        factors: &[(Vec3, Vec3)],
    ) -> Result<std::time::Duration, RelightError> {
        let mut timer = scene_core::gpu::compute::PassTimer::new(&self.ctx, 1);
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        let writes = timer.as_mut().and_then(|t| t.writes("relight"));
        self.encode_relight(&mut encoder, factors, Vec3::ZERO, writes)?;
        if let Some(t) = &timer {
            t.resolve(&mut encoder);
        }
        let t0 = std::time::Instant::now();
        self.ctx.queue.submit([encoder.finish()]);
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| gpu(GpuError::Readback(e.to_string())))?;
        let wall = t0.elapsed();
        match &timer {
            Some(t) => Ok(t
                .read(&self.ctx)
                .map_err(gpu)?
                .first()
                .map_or(wall, |(_, d)| *d)),
            None => Ok(wall),
        }
    }

    /// Bytes resident on the GPU (solutions, element table, relit irradiance).
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Storage precision.
    pub fn precision(&self) -> Precision {
        self.precision
    }

    /// Number of light sources of the solution.
    pub fn sources(&self) -> usize {
        self.k
    }

    /// Number of elements of the solution (groups of mesh elements,
    /// [`Meshing::groups`]).
    pub fn elements(&self) -> usize {
        self.elements
    }

    /// Number of mesh elements the display draws (0 for [`GpuRelight::relight_only`]).
    pub fn mesh_elements(&self) -> usize {
        self.mesh_elements
    }

    /// True once [`GpuRelight::set_shadowed_direct`] has set the per-frame direct light.
    pub fn has_shadowed_direct(&self) -> bool {
        self.shadowed.is_some()
    }

    /// The factor pairs as the shaders read them (two `vec4` per source).
    fn factor_data(factors: &[(Vec3, Vec3)]) -> Vec<[f32; 4]> {
        factors
            .iter()
            .flat_map(|(d, i)| [d.extend(0.0).to_array(), i.extend(0.0).to_array()])
            .collect()
    }

    fn check_factors(&self, factors: &[(Vec3, Vec3)]) -> Result<(), RelightError> {
        if factors.len() != self.k {
            return Err(RelightError::InvalidSetting(format!(
                "{} light factors for a solution of {} sources",
                factors.len(),
                self.k
            )));
        }
        Ok(())
    }

    /// Records eq. 1 over every element into `encoder` (result in the GPU buffer read by
    /// [`GpuRelight::read_irradiance`]); `factors` and `base` as [`Packed::relight`].
    pub fn encode_relight(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        factors: &[(Vec3, Vec3)],
        base: Vec3,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) -> Result<(), RelightError> {
        self.check_factors(factors)?;
        let params = RelightParams {
            n: self.elements as u32,
            k: self.k as u32,
            pad: [0; 2],
            base: base.extend(0.0).to_array(),
        };
        self.writer.write(
            encoder,
            &self.relight_params,
            0,
            bytemuck::bytes_of(&params),
        );
        let data = Self::factor_data(factors);
        self.writer.write(
            encoder,
            &self.relight_factors,
            0,
            bytemuck::cast_slice(&data),
        );
        self.writer.finish(encoder);
        let groups = (self.elements as u32).div_ceil(GROUP).max(1);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("relight-pr relight"),
            timestamp_writes: timestamps,
        });
        pass.set_pipeline(&self.relight_pass.pipeline);
        pass.set_bind_group(0, &self.relight_bind, &[]);
        pass.dispatch_workgroups(groups.min(MAX_GROUPS_X), groups.div_ceil(MAX_GROUPS_X), 1);
        Ok(())
    }

    /// Eq. 1 on the GPU, read back: each element's irradiance.
    pub fn relight(&self, factors: &[(Vec3, Vec3)], base: Vec3) -> Result<Vec<Vec3>, RelightError> {
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        self.encode_relight(&mut encoder, factors, base, None)?;
        self.ctx.queue.submit([encoder.finish()]);
        self.read_irradiance()
    }

    /// The irradiance the last relight pass wrote.
    pub fn read_irradiance(&self) -> Result<Vec<Vec3>, RelightError> {
        let v: Vec<[f32; 4]> = self.ctx.read_buffer_as(&self.irradiance).map_err(gpu)?;
        Ok(v.iter()
            .take(self.elements)
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect())
    }

    /// The hardware display: the image of `g` (a G-buffer of [`Meshing::element_scene`]
    /// seen from `view`), each pixel combining the per-light vertex radiosity with
    /// `factors` and `base` ([`crate::relight::weights`] with the direct part), times its
    /// albedo, plus its element's glow; with `pixel_direct` (pixel-major, k per pixel,
    /// [`crate::display::pixel_direct`]) the vertices' direct part is left out and each
    /// pixel adds its own direct light times the direct factors. Equals
    /// [`crate::display::compose`] with smooth shading. Records, submits and reads the
    /// image back; [`GpuRelight::encode_display`] is the same without the readback.
    pub fn display(
        &self,
        g: &GpuGBuffer,
        view: &View,
        factors: &[(Vec3, Vec3)],
        base: Vec3,
        pixel_direct: Option<&[Vec3]>,
    ) -> Result<Image, RelightError> {
        let direct = pixel_direct.map_or(Direct::Elements, Direct::Values);
        self.display_with(g, view, factors, base, direct)
    }

    /// [`GpuRelight::display`] with the direct light of the shadow-mapped lights set by
    /// [`GpuRelight::set_shadowed_direct`], evaluated at every pixel on the GPU: equals
    /// [`crate::display::compose`] over [`crate::display::pixel_direct_shadowed`].
    pub fn display_shadowed(
        &self,
        g: &GpuGBuffer,
        view: &View,
        factors: &[(Vec3, Vec3)],
        base: Vec3,
    ) -> Result<Image, RelightError> {
        self.display_with(g, view, factors, base, Direct::Shadowed)
    }

    fn display_with(
        &self,
        g: &GpuGBuffer,
        view: &View,
        factors: &[(Vec3, Vec3)],
        base: Vec3,
        direct: Direct<'_>,
    ) -> Result<Image, RelightError> {
        let (w, h) = (g.width, g.height);
        let pixels = w as usize * h as usize;
        let ctx = &self.ctx;
        let image = ctx.pixel_buffer("relight image", w, h);
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        self.encode_display_with(&mut encoder, g, view, factors, base, direct, &image)?;
        ctx.queue.submit([encoder.finish()]);
        let v: Vec<[f32; 4]> = ctx.read_buffer_as(&image).map_err(gpu)?;
        Ok(Image {
            width: w,
            height: h,
            pixels: v
                .iter()
                .take(pixels)
                .map(|p| Vec3::new(p[0], p[1], p[2]))
                .collect(),
        })
    }

    /// Uploads `set` (scene-core's shadow-mapped lights of the scene this solution is of)
    /// with `slots`, the source that holds each light ([`crate::display::light_slots`]),
    /// and compiles the direct pass: what [`GpuRelight::encode_display_shadowed`] reads,
    /// averaging each pixel over a `footprint` x `footprint` grid
    /// ([`crate::display::pixel_direct_shadowed`]). Once per scene or light rig (the maps
    /// are view-independent), never per frame. Fails on a slot count that is not the set's
    /// light count or a footprint outside 1 to [`crate::display::MAX_FOOTPRINT`], and with
    /// [`RelightError::Budget`] before allocating maps over the adapter's binding limit.
    pub fn set_shadowed_direct(
        &mut self,
        set: &LightSet,
        slots: &[Option<usize>],
        footprint: u32,
    ) -> Result<(), RelightError> {
        if !(1..=crate::display::MAX_FOOTPRINT).contains(&footprint) {
            return Err(RelightError::InvalidSetting(format!(
                "footprint {footprint}: expected 1 to {}",
                crate::display::MAX_FOOTPRINT
            )));
        }
        if slots.len() != set.lights.len() {
            return Err(RelightError::InvalidSetting(format!(
                "{} light slots for {} lights",
                slots.len(),
                set.lights.len()
            )));
        }
        let ctx = &self.ctx;
        let limit = ctx.storage_binding_limit();
        let lights = gpu_lights(set);
        let texel_bytes = set.shadow_texels.len() as u64 * 4;
        check_binding("shadow maps", texel_bytes, limit)?;
        check_binding(
            "light table",
            std::mem::size_of_val(lights.as_slice()) as u64,
            limit,
        )?;
        let pass = ComputePass::new(
            &ctx.device,
            "relight-pr direct",
            &DIRECT,
            &[
                uniform(0),
                storage_buffer(1),
                storage_buffer_rw(2),
                scene_core::gpu::layout::float_texture(3),
                scene_core::gpu::layout::float_texture(4),
                scene_core::gpu::layout::texture(5, wgpu::TextureSampleType::Uint),
                storage_buffer(6),
                storage_buffer(7),
                storage_buffer(8),
            ],
            &[],
        )
        .map_err(gpu)?;
        // Storage bindings may not be empty: a set without lights or maps binds one zero.
        let nonempty = |bytes: &[u8], min: usize| {
            let mut v = bytes.to_vec();
            v.resize(v.len().max(min), 0);
            v
        };
        let slot_words: Vec<u32> = slots
            .iter()
            .map(|s| s.map_or(u32::MAX, |m| m as u32))
            .collect();
        let shadowed = ctx
            .validated(|| ShadowedDirect {
                params: ctx.frame_buffer(
                    "relight direct params",
                    std::mem::size_of::<DirectParams>() as u64,
                    wgpu::BufferUsages::UNIFORM,
                ),
                lights: ctx.storage_with(
                    "relight direct lights",
                    &nonempty(bytemuck::cast_slice(&lights), 144),
                    wgpu::BufferUsages::empty(),
                ),
                texels: ctx.storage_with(
                    "relight direct shadow maps",
                    &nonempty(bytemuck::cast_slice(&set.shadow_texels), 4),
                    wgpu::BufferUsages::COPY_DST,
                ),
                texel_count: set.shadow_texels.len(),
                slots: ctx.storage_with(
                    "relight direct slots",
                    &nonempty(bytemuck::cast_slice(&slot_words), 4),
                    wgpu::BufferUsages::empty(),
                ),
                count: lights.len() as u32,
                shadow: ShadowParams::of(set),
                footprint,
                pass,
                bind: std::sync::Mutex::new(Keyed::new()),
            })
            .map_err(gpu)?;
        self.shadowed = Some(shadowed);
        Ok(())
    }

    /// Records, into `encoder`, a copy of the shadow maps `maps` rendered on the GPU from
    /// the engine's meshes (scene-core's `ShadowMapPass`, made for the light set given to
    /// [`GpuRelight::set_shadowed_direct`]) into the direct pass' own: maps re-rendered
    /// after a light or a caster moved, with nothing read back and nothing created. Refused
    /// before `set_shadowed_direct`, or when `maps` holds another number of texels.
    pub fn copy_shadow_texels(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        maps: &scene_core::shadowed_lights::gpu_maps::ShadowMapPass,
    ) -> Result<(), RelightError> {
        let Some(s) = &self.shadowed else {
            return Err(RelightError::InvalidSetting(
                "no shadow-mapped lights on the GPU: call set_shadowed_direct first".into(),
            ));
        };
        if maps.texel_count() != s.texel_count {
            return Err(RelightError::InvalidSetting(format!(
                "GPU shadow maps of {} texels for a light set of {}",
                maps.texel_count(),
                s.texel_count
            )));
        }
        if s.texel_count > 0 {
            encoder.copy_buffer_to_buffer(maps.texels(), 0, &s.texels, 0, s.texel_count as u64 * 4);
        }
        Ok(())
    }

    /// Records [`GpuRelight::display`] into `encoder`, writing the image into `output` (at
    /// least `g.width * g.height` `vec4<f32>`, row-major, radiance in `xyz`, e.g. from
    /// [`GpuContext::pixel_buffer`]). Nothing is read back: what an interactive frame
    /// loop needs.
    #[allow(clippy::too_many_arguments)]
    pub fn encode_display(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        g: &GpuGBuffer,
        view: &View,
        factors: &[(Vec3, Vec3)],
        base: Vec3,
        pixel_direct: Option<&[Vec3]>,
        output: &wgpu::Buffer,
    ) -> Result<(), RelightError> {
        let direct = pixel_direct.map_or(Direct::Elements, Direct::Values);
        self.encode_display_with(encoder, g, view, factors, base, direct, output)
    }

    /// Records [`GpuRelight::display_shadowed`] into `encoder`: the direct pass (every
    /// shadow-mapped light at every pixel of `g`, per source) and the display reading it,
    /// into `output` as [`GpuRelight::encode_display`] does. What a frame of a moving camera
    /// costs: nothing is kept from the previous view. Fails when
    /// [`GpuRelight::set_shadowed_direct`] was not called.
    pub fn encode_display_shadowed(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        g: &GpuGBuffer,
        view: &View,
        factors: &[(Vec3, Vec3)],
        base: Vec3,
        output: &wgpu::Buffer,
    ) -> Result<(), RelightError> {
        self.encode_display_with(encoder, g, view, factors, base, Direct::Shadowed, output)
    }

    #[allow(clippy::too_many_arguments)]
    fn encode_display_with(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        g: &GpuGBuffer,
        view: &View,
        factors: &[(Vec3, Vec3)],
        base: Vec3,
        direct_in: Direct<'_>,
        output: &wgpu::Buffer,
    ) -> Result<(), RelightError> {
        self.check_factors(factors)?;
        let (w, h) = (g.width, g.height);
        GpuContext::check_pixel_buffer(output, w, h, "display output").map_err(gpu)?;
        let pixels = w as usize * h as usize;
        let frustum = FrustumReconstruction::new(view).uniform();
        let params = DisplayParams {
            frustum,
            width: w,
            height: h,
            k: self.k as u32,
            elements: self.mesh_elements as u32,
            base: base.extend(0.0).to_array(),
        };
        let ctx = &self.ctx;
        let (pass, direct, direct_bytes): (_, Vec<[f32; 4]>, u64) = match direct_in {
            Direct::Values(values) => {
                if values.len() != pixels * self.k {
                    return Err(RelightError::InvalidSetting(format!(
                        "per-pixel direct light of {} values for {pixels} pixels and {} sources",
                        values.len(),
                        self.k
                    )));
                }
                let v: Vec<[f32; 4]> = values.iter().map(|v| v.extend(0.0).to_array()).collect();
                let bytes = std::mem::size_of_val(v.as_slice()) as u64;
                (&self.display_per_pixel, v, bytes)
            }
            Direct::Shadowed => {
                if self.shadowed.is_none() {
                    return Err(RelightError::InvalidSetting(
                        "no shadow-mapped lights on the GPU: call set_shadowed_direct first".into(),
                    ));
                }
                (
                    &self.display_per_pixel,
                    Vec::new(),
                    (pixels * self.k) as u64 * 16,
                )
            }
            Direct::Elements => (&self.display_pass, Vec::new(), 0),
        };
        let mut kept = self.direct.lock().unwrap_or_else(|e| e.into_inner());
        let direct_buf = kept.ensure(&ctx.device, direct_bytes).clone();
        let generation = kept.generation();
        let key = DisplayKey {
            textures: [g.albedo.clone(), g.depth.clone(), g.triangle_id.clone()],
            output: output.clone(),
            per_pixel: !matches!(direct_in, Direct::Elements),
            direct: generation,
        };
        drop(kept);
        let mut cached = self.display_bind.lock().unwrap_or_else(|e| e.into_inner());
        let bind = cached.get_or_make(key, |_| {
            let buffers = [
                &self.display_params,
                &self.vertex_words,
                &self.display_factors,
                &self.element_table,
                &direct_buf,
                output,
            ];
            let textures = [&g.albedo, &g.depth, &g.triangle_id];
            pass.bind_buffers_then_textures(&ctx.device, &buffers, &textures)
        });
        // The direct pass' bind group (shadow-mapped lights only).
        let shadowed = match (direct_in, &self.shadowed) {
            (Direct::Shadowed, Some(s)) if self.k > 0 => {
                let key = (
                    [g.normal.clone(), g.depth.clone(), g.triangle_id.clone()],
                    generation,
                );
                let mut cached = s.bind.lock().unwrap_or_else(|e| e.into_inner());
                cached.get_or_make(key, |_| {
                    let views = [&g.normal, &g.depth, &g.triangle_id]
                        .map(|t| t.create_view(&Default::default()));
                    s.pass.bind(
                        &ctx.device,
                        &[
                            s.params.as_entire_binding(),
                            s.slots.as_entire_binding(),
                            direct_buf.as_entire_binding(),
                            wgpu::BindingResource::TextureView(&views[0]),
                            wgpu::BindingResource::TextureView(&views[1]),
                            wgpu::BindingResource::TextureView(&views[2]),
                            s.lights.as_entire_binding(),
                            s.texels.as_entire_binding(),
                            self.element_table.as_entire_binding(),
                        ],
                    )
                });
                let params = DirectParams {
                    frustum,
                    width: w,
                    height: h,
                    k: self.k as u32,
                    light_count: s.count,
                    shadow_params: s.shadow,
                    footprint: s.footprint,
                    pad: [0; 3],
                };
                self.writer
                    .write(encoder, &s.params, 0, bytemuck::bytes_of(&params));
                Some((s, cached))
            }
            _ => None,
        };
        self.writer.write(
            encoder,
            &self.display_params,
            0,
            bytemuck::bytes_of(&params),
        );
        let data = Self::factor_data(factors);
        self.writer.write(
            encoder,
            &self.display_factors,
            0,
            bytemuck::cast_slice(&data),
        );
        self.writer
            .write(encoder, &direct_buf, 0, bytemuck::cast_slice(&direct));
        self.writer.finish(encoder);
        if let Some((s, cached)) = &shadowed
            && let Some(bind) = cached.value()
        {
            s.pass.dispatch(encoder, bind, w, h, None);
        }
        pass.dispatch(encoder, bind, w, h, None);
        Ok(())
    }
}

fn gpu(e: GpuError) -> RelightError {
    RelightError::Gpu(Box::new(e))
}

/// Refuses a buffer of `bytes` over the adapter's binding `limit`, naming `what`.
fn check_binding(what: &str, bytes: u64, limit: u64) -> Result<(), RelightError> {
    if bytes > limit {
        return Err(RelightError::Budget(scene_core::BudgetExceeded {
            what: format!("the {what}"),
            needed: bytes,
            limit,
            unit: "bytes",
            hint: "this adapter's binding limit; use Precision::F16 or fewer elements".into(),
        }));
    }
    Ok(())
}

/// Every struct written for the shaders has the layout naga gives its WGSL twin, in the
/// module the composer builds (a field moved on one side fails here).
#[cfg(test)]
mod layout_tests {
    use super::*;
    use scene_core::check_layout;

    #[test]
    fn uniforms_and_tables_match_their_wgsl_structs() {
        let relight = RELIGHT.compose().unwrap();
        check_layout!(
            &relight,
            "RelightParams",
            RelightParams {
                n,
                k,
                pad0: pad,
                pad1: pad + 4,
                base,
            }
        )
        .unwrap();
        let display = DISPLAY.compose().unwrap();
        check_layout!(
            &display,
            "DisplayParams",
            DisplayParams {
                frustum,
                width,
                height,
                k,
                elements,
                base,
            }
        )
        .unwrap();
        let direct = DIRECT.compose().unwrap();
        check_layout!(
            &direct,
            "DirectParams",
            DirectParams {
                frustum,
                width,
                height,
                k,
                light_count,
                shadow_params,
                footprint,
                pad0: pad,
                pad1: pad + 4,
                pad2: pad + 8,
            }
        )
        .unwrap();
        check_layout!(
            &display,
            "Element",
            GpuElement {
                a,
                b,
                c,
                emission,
                vertex
            }
        )
        .unwrap();
    }
}
