//! The GPU path: the same frame as [`crate::render_cpu`] in wgpu compute passes, one shader
//! per pass in `shaders/isr/` (each with its pipeline and bind groups in [`crate::passes`]), from a [`GpuGBuffer`] made by anyone into a caller-provided texture, with no
//! readback in the frame.
//!
//! Engine integration, a frame per submit:
//!
//! ```no_run
//! use isr::{GpuIsr, GpuIsrInputs, LightSet, IsrSettings, ShadowSettings};
//! use scene_core::gpu::{GpuContext, GpuGBuffer};
//! use scene_core::{View, builtin};
//!
//! let ctx = GpuContext::new().unwrap();
//! let scene = builtin::scene("cornell").unwrap();
//! let view = View::from_camera(&scene.cameras[0]);
//! // Once per scene: lights, shadow maps and emitters, uploaded.
//! let mut isr = GpuIsr::new(&ctx, &LightSet::new(&scene, &ShadowSettings::default()).unwrap()).unwrap();
//! // The engine's own G-buffer (here an empty one) and its HDR target (Rgba32Float or
//! // Rgba16Float, with STORAGE_BINDING usage).
//! let gbuffer = GpuGBuffer::new(&ctx, 1024, 768).unwrap();
//! let target = ctx.device.create_texture(&wgpu::TextureDescriptor {
//!     label: Some("hdr"),
//!     size: wgpu::Extent3d { width: 1024, height: 768, depth_or_array_layers: 1 },
//!     mip_level_count: 1,
//!     sample_count: 1,
//!     dimension: wgpu::TextureDimension::D2,
//!     format: wgpu::TextureFormat::Rgba16Float,
//!     usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
//!     view_formats: &[],
//! });
//! let inputs = GpuIsrInputs { full: &gbuffer, coarse: None, view: &view };
//! // Records every pass into the engine's encoder; the engine submits it.
//! let mut encoder = ctx.device.create_command_encoder(&Default::default());
//! isr.encode(&mut encoder, &inputs, &IsrSettings::screen_space(), &target).unwrap();
//! ctx.queue.submit([encoder.finish()]);
//! ```

use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use scene_core::gbuffer::downsample::{GpuDownsampler, coarse_size};
use scene_core::gpu::{FrameWriter, GpuContext, GpuError, GpuGBuffer, Keyed, PassTimer};
use scene_core::lights::LightState;
use scene_core::{GBuffer, Image, View};

use crate::geometry::Screen;
use crate::light_senders::{GpuLightSender, LightSenders};
use crate::light_set::LightSet;
use crate::passes::{
    BlurPass, LightBuffers, LightSendersPass, LightingPass, RadiosityPass, UpsamplePass, Variant,
    bind_lighting,
};
use crate::radiosity::SamplePattern;
use crate::settings::{Blur, Estimator, IsrSettings, Sender};
use crate::{IsrError, PassTimings};

/// Workgroup edge of every ISR shader (8 x 8 invocations).
pub const WORKGROUP: u32 = scene_core::gpu::WORKGROUP;

/// The per-frame uniform block (`Globals` in the shaders).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Globals {
    /// [`Screen::uniform`]; the `w` of the fifth row is the scene's extent.
    pub view: [[f32; 4]; 5],
    /// Full width, height; coarse width, height.
    pub sizes: [u32; 4],
    /// Samples, flags, light count, blur radius.
    pub config: [u32; 4],
    /// `k_dl`, `k_ssao`, `k_isr`, world radius.
    pub k: [f32; 4],
    /// Blur sigma, upsampling epsilon, upsampling normal power, ESM exponent.
    pub filters: [f32; 4],
    /// Shadow normal offset, depth bias (texels), unused, unused.
    pub shadow: [f32; 4],
    /// Eq. 24's vectors ([`scene_core::view::FrustumReconstruction::uniform`]).
    pub frustum: [[f32; 4]; 6],
    /// World to clip space, by columns (the light-space senders' projection).
    pub view_proj: [[f32; 4]; 4],
    /// Light-space senders: how many, whether each is counted once (1) or not (0), whether
    /// the gather is interleaved (1) or not (0), whether it reads their visibility maps (1)
    /// or not (0). Zero count: the pass does not run.
    pub senders: [u32; 4],
    /// [`LightSenders::phase_offsets`], four to a row (the last three unused).
    pub sender_phases: [[u32; 4]; 5],
}

/// Flag bits of [`Globals::config`]`[1]`.
pub mod flags {
    /// The indirect term is on.
    pub const INDIRECT: u32 = 1;
    /// SSAO is on.
    pub const SSAO: u32 = 2;
    /// AO multiplies the indirect term only.
    pub const AO_INDIRECT_ONLY: u32 = 4;
    /// Edge-aware blur.
    pub const EDGE_AWARE: u32 = 8;
    /// Eq. 25 as published.
    pub const THESIS: u32 = 16;
    /// Lit senders.
    pub const LIT: u32 = 32;
}

impl Globals {
    /// The block for one frame.
    pub fn new(
        screen: &Screen,
        scene: &LightSet,
        settings: &IsrSettings,
        full: (u32, u32),
        coarse: (u32, u32),
    ) -> Self {
        let mut view = screen.uniform();
        view[4][3] = scene.extent;
        let mut f = 0;
        for (on, bit) in [
            (settings.indirect, flags::INDIRECT),
            (settings.ssao, flags::SSAO),
            (settings.ao_indirect_only, flags::AO_INDIRECT_ONLY),
            (settings.blur == Blur::EdgeAware, flags::EDGE_AWARE),
            (settings.estimator == Estimator::Thesis, flags::THESIS),
            (settings.sender == Sender::Lit, flags::LIT),
        ] {
            if on {
                f |= bit;
            }
        }
        Self {
            view,
            sizes: [full.0, full.1, coarse.0, coarse.1],
            config: [
                settings.samples,
                f,
                scene.lights.len() as u32,
                settings.blur_radius,
            ],
            k: [
                settings.k_dl,
                settings.k_ssao,
                settings.k_isr,
                settings.radius.world(scene.extent),
            ],
            filters: [
                settings.blur_sigma,
                settings.upsample_epsilon,
                settings.upsample_normal_power,
                scene.shadows.esm_exponent,
            ],
            shadow: [
                scene.shadows.normal_offset,
                scene.shadows.depth_bias,
                0.0,
                0.0,
            ],
            frustum: screen.reconstruction.uniform(),
            view_proj: [[0.0; 4]; 4],
            senders: [0; 4],
            sender_phases: [[0; 4]; 5],
        }
    }
}

pub use scene_core::shadowed_lights::gpu::{GpuLight, gpu_emitters, gpu_lights};

fn view_of(t: &wgpu::Texture) -> wgpu::TextureView {
    t.create_view(&Default::default())
}

/// An Rgba32Float texture a pass writes and a later pass (or a readback) reads.
fn rgba_texture(ctx: &GpuContext, label: &str, width: u32, height: u32) -> wgpu::Texture {
    ctx.create_texture_2d(
        label,
        width,
        height,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::STORAGE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
    )
}

/// The inputs of a GPU frame.
#[derive(Clone, Copy, Debug)]
pub struct GpuIsrInputs<'a> {
    /// The full-resolution G-buffer (anyone's: only its colour textures are read).
    pub full: &'a GpuGBuffer,
    /// The coarse G-buffer; `None` downsamples `full` on the GPU (half size, with
    /// [`IsrSettings::downsample`]).
    pub coarse: Option<&'a GpuGBuffer>,
    /// The view both were rendered from.
    pub view: &'a View,
}

/// The intermediate buffers of a GPU frame ([`GpuIsr::intermediate`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Intermediate {
    /// Coarse: the light each sender sends (`Lit` senders only).
    Senders,
    /// Coarse: the gathered indirect irradiance (`xyz`) and ambient accessibility (`w`).
    Radiosity,
    /// Coarse: the same after the blur.
    Blurred,
    /// Full size: the same after the bilateral upsampling.
    Upsampled,
}

/// Intermediate textures of one size.
struct Targets {
    full: (u32, u32),
    coarse: (u32, u32),
    coarse_gbuffer: Option<GpuGBuffer>,
    senders: wgpu::Texture,
    /// The ISR + SSAO pass' output when the light-space senders' pass adds to it (into
    /// `radiosity`); unused otherwise.
    screen_radiosity: wgpu::Texture,
    radiosity: wgpu::Texture,
    tmp: wgpu::Texture,
    blurred: wgpu::Texture,
    upsampled: wgpu::Texture,
}

/// Which pass a recorded command belongs to (for timings).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    Downsample,
    Senders,
    Radiosity,
    LightSenders,
    Blur,
    Upsample,
    Lighting,
}

impl Stage {
    fn label(self) -> &'static str {
        match self {
            Stage::Downsample => "downsample",
            Stage::Senders => "senders",
            Stage::Radiosity => "radiosity",
            Stage::LightSenders => "light senders",
            Stage::Blur => "blur",
            Stage::Upsample => "upsample",
            Stage::Lighting => "lighting",
        }
    }

    fn add(self, timings: &mut PassTimings, t: std::time::Duration) {
        match self {
            Stage::Downsample => timings.downsample += t,
            Stage::Senders => timings.senders += t,
            Stage::Radiosity => timings.radiosity += t,
            Stage::LightSenders => timings.light_senders += t,
            Stage::Blur => timings.blur += t,
            Stage::Upsample => timings.upsample += t,
            Stage::Lighting => timings.lighting += t,
        }
    }
}

/// Where passes are recorded: one caller's encoder; one encoder timed by timestamp queries;
/// or one submit per pass, timed by the wall clock (adapters without timestamps).
enum Recorder<'a> {
    Into(&'a mut wgpu::CommandEncoder),
    Timestamps(wgpu::CommandEncoder, PassTimer, Vec<Stage>),
    WallClock(&'a GpuContext, PassTimings),
}

impl Recorder<'_> {
    /// Writes `bytes` into `target` before the frame's passes: by a copy recorded in the
    /// frame's encoder (the wall-clock recorder submits each pass at once and writes
    /// through the queue).
    fn upload(
        &mut self,
        writer: &FrameWriter,
        ctx: &GpuContext,
        target: &wgpu::Buffer,
        bytes: &[u8],
    ) {
        match self {
            Recorder::Into(encoder) => writer.write(encoder, target, 0, bytes),
            Recorder::Timestamps(encoder, ..) => writer.write(encoder, target, 0, bytes),
            Recorder::WallClock(..) => ctx.queue.write_buffer(target, 0, bytes),
        }
    }

    /// Closes the frame's staging: its chunks come back once the encoder's submission has
    /// run.
    fn finish(&mut self, writer: &FrameWriter) {
        match self {
            Recorder::Into(encoder) => writer.finish(encoder),
            Recorder::Timestamps(encoder, ..) => writer.finish(encoder),
            Recorder::WallClock(..) => {}
        }
    }

    /// Records the dispatches of one pass: `f` gets the encoder and the timestamp writes to
    /// put on its compute pass (at most one timed compute pass per call).
    fn pass(
        &mut self,
        stage: Stage,
        f: impl FnOnce(&mut wgpu::CommandEncoder, Option<wgpu::ComputePassTimestampWrites<'_>>),
    ) {
        match self {
            Recorder::Into(encoder) => f(encoder, None),
            Recorder::Timestamps(encoder, timer, stages) => {
                stages.push(stage);
                let writes = timer.writes(stage.label());
                f(encoder, writes)
            }
            Recorder::WallClock(ctx, timings) => {
                let start = Instant::now();
                let mut encoder = ctx.device.create_command_encoder(&Default::default());
                f(&mut encoder, None);
                ctx.queue.submit([encoder.finish()]);
                let _ = ctx.device.poll(wgpu::PollType::wait_indefinitely());
                stage.add(timings, start.elapsed());
            }
        }
    }
}

/// Timed passes per frame at most (downsample, senders, radiosity, light-space senders, two
/// blur directions, upsample, lighting).
const MAX_TIMED_PASSES: u32 = 8;

/// ISR on the GPU for one light set: pipelines (all compiled in [`GpuIsr::new`]), the
/// lights, shadow maps and emitters in storage buffers, and intermediate textures
/// (recreated when the size changes). A frame's uniforms are copied into one buffer by a
/// command of the frame's own encoder (staged in a `wgpu::util::StagingBelt` whose chunks
/// return when their submission has run), so several views can be encoded before one
/// submit; the bind groups are kept while the frame's textures stay the same. A steady
/// stream of frames therefore creates no GPU object (tested with wgpu's counters). A new
/// [`LightState`] rewrites the light buffers ([`GpuIsr::apply`]) and compiles nothing.
pub struct GpuIsr {
    ctx: GpuContext,
    extent: f32,
    light_set: LightSet,
    light_state: u64,
    downsample: GpuDownsampler,
    lighting: LightingPass,
    radiosity: RadiosityPass,
    light_senders_pass: LightSendersPass,
    /// The light-space senders ([`GpuIsr::set_light_senders`]).
    light_senders: Option<UploadedSenders>,
    blur: BlurPass,
    upsample: UpsamplePass,
    lights: wgpu::Buffer,
    shadow_texels: wgpu::Buffer,
    /// Texels of the light set's shadow maps (the light set kept has none).
    shadow_texel_count: usize,
    emitter_of: wgpu::Buffer,
    emitters: wgpu::Buffer,
    pattern: Option<(u32, wgpu::Buffer)>,
    dummy: wgpu::Texture,
    targets: Option<Targets>,
    /// Bumped whenever `targets` or `pattern` is recreated (the cached bind groups
    /// reference them).
    generation: u64,
    /// The frame's uniforms: one buffer, rewritten by a copy recorded in each frame's own
    /// encoder (so frames encoded before one submit each read their own values).
    globals: wgpu::Buffer,
    /// Where those copies are staged: chunks return once their submission has run, so a
    /// steady stream of frames allocates nothing.
    writer: FrameWriter,
    /// The bind groups of the last frame's inputs, reused while they stay the same.
    bound: Keyed<BindKey, Bound>,
    /// Set by [`GpuIsr::apply`]: the next frame rewrites the light and emitter buffers.
    lights_changed: bool,
}

/// The light-space senders on the GPU: their buffer and what the frame's globals say of them.
struct UploadedSenders {
    buffer: wgpu::Buffer,
    /// Their visibility maps (one zero when they have none).
    depths: wgpu::Buffer,
    /// [`Globals::senders`] without the frame's settings.
    senders: [u32; 4],
    /// [`Globals::sender_phases`].
    phases: [[u32; 4]; 5],
}

/// What a frame's bind groups depend on: the caller's textures (by identity), the
/// intermediate textures and pattern (by generation) and the passes that run.
#[derive(Clone, Debug, PartialEq)]
struct BindKey {
    full: [wgpu::Texture; 4],
    coarse: Option<[wgpu::Texture; 4]>,
    output: wgpu::Texture,
    generation: u64,
    downsample: scene_core::gbuffer::DownsampleMode,
    run_isr: bool,
    lit: bool,
    light_senders: bool,
    blur: bool,
    half: bool,
}

/// A frame's bind groups (`None` for passes that do not run).
struct Bound {
    downsample: Option<wgpu::BindGroup>,
    senders: Option<wgpu::BindGroup>,
    radiosity: Option<wgpu::BindGroup>,
    light_senders: Option<wgpu::BindGroup>,
    blur: Option<[wgpu::BindGroup; 2]>,
    upsample: Option<wgpu::BindGroup>,
    compose: wgpu::BindGroup,
}

fn textures_of(g: &GpuGBuffer) -> [wgpu::Texture; 4] {
    [
        g.albedo.clone(),
        g.normal.clone(),
        g.depth.clone(),
        g.triangle_id.clone(),
    ]
}

impl std::fmt::Debug for GpuIsr {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuIsr")
            .field("adapter", &self.ctx.adapter_summary())
            .field("lights", &self.light_set.lights.len())
            .finish()
    }
}

impl GpuIsr {
    /// Compiles the pipelines and uploads `lights` (their shadow maps and emitters, with
    /// their current factors). Errors when a buffer exceeds the device's storage-buffer
    /// limit.
    pub fn new(ctx: &GpuContext, lights: &LightSet) -> Result<Self, IsrError> {
        ctx.validated_with(|| Self::create(ctx, lights))
    }

    fn create(ctx: &GpuContext, scene: &LightSet) -> Result<Self, IsrError> {
        let device = &ctx.device;
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        let limit = device.limits().max_storage_buffer_binding_size;
        let texel_bytes = scene.shadow_texels.len() as u64 * 4;
        if texel_bytes > limit {
            return Err(IsrError::Budget(scene_core::BudgetExceeded {
                what: "the shadow maps".into(),
                needed: texel_bytes,
                limit,
                unit: "bytes",
                hint: "the device's storage buffer limit; lower ShadowSettings resolutions or \
                       max_texels"
                    .into(),
            }));
        }
        let mut lights = gpu_lights(scene);
        if lights.is_empty() {
            // A scene without lights: the shader's array needs one whole element to bind
            // (its light count stays 0, so it is never read).
            lights.push(bytemuck::Zeroable::zeroed());
        }
        let table = gpu_emitters(scene);
        let per_triangle: &[u32] = if scene.emitters.entries.is_empty() {
            // No emitters: no triangle needs looking up.
            &[]
        } else {
            &scene.emitters.per_triangle
        };
        let this = Self {
            ctx: ctx.clone(),
            extent: scene.extent,
            light_set: LightSet {
                shadow_texels: Vec::new(),
                ..scene.clone()
            },
            shadow_texel_count: scene.shadow_texels.len(),
            light_state: LightState::default().fingerprint(),
            downsample: GpuDownsampler::new(ctx)?,
            lighting: LightingPass::new(device)?,
            radiosity: RadiosityPass::new(device)?,
            light_senders_pass: LightSendersPass::new(device)?,
            light_senders: None,
            blur: BlurPass::new(device)?,
            upsample: UpsamplePass::new(device)?,
            lights: ctx.buffer_with("isr lights", bytemuck::cast_slice(&lights), storage),
            shadow_texels: ctx.buffer_with(
                "isr shadow maps",
                bytemuck::cast_slice(&scene.shadow_texels),
                storage,
            ),
            emitter_of: ctx.buffer_with(
                "isr emitter index",
                bytemuck::cast_slice(per_triangle),
                storage,
            ),
            emitters: ctx.buffer_with("isr emitters", bytemuck::cast_slice(&table), storage),
            pattern: None,
            dummy: rgba_texture(ctx, "isr dummy", 1, 1),
            targets: None,
            generation: 0,
            globals: ctx.frame_buffer(
                "isr globals",
                std::mem::size_of::<Globals>() as u64,
                wgpu::BufferUsages::UNIFORM,
            ),
            writer: FrameWriter::new(device, 4096),
            bound: Keyed::new(),
            lights_changed: false,
        };
        // Every pipeline now, none in a frame: a first frame must not hitch.
        this.downsample.compile_all()?;
        for variant in [
            Variant::Senders,
            Variant::Compose {
                with_isr: false,
                half: false,
            },
            Variant::Compose {
                with_isr: true,
                half: false,
            },
            Variant::Compose {
                with_isr: false,
                half: true,
            },
            Variant::Compose {
                with_isr: true,
                half: true,
            },
        ] {
            this.lighting.pipeline(device, variant);
        }
        Ok(this)
    }

    /// The context the pipelines live on.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// Records, into `encoder`, a copy of the shadow maps `maps` rendered on the GPU from
    /// the engine's meshes (scene-core's `ShadowMapPass`, made for the light set this ISR
    /// was made with) into ISR's own: how maps re-rendered after a light or a caster moved
    /// reach ISR, with nothing read back and nothing created. Refused when `maps` holds
    /// another number of texels than ISR's light set.
    pub fn copy_shadow_texels(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        maps: &scene_core::shadowed_lights::gpu_maps::ShadowMapPass,
    ) -> Result<(), IsrError> {
        let count = self.shadow_texel_count;
        if maps.texel_count() != count {
            return Err(IsrError::Gpu(GpuError::BadLength {
                what: "the GPU shadow maps (texels) for ISR's light set",
                expected: count,
                found: maps.texel_count(),
            }));
        }
        if count > 0 {
            encoder.copy_buffer_to_buffer(
                maps.texels(),
                0,
                &self.shadow_texels,
                0,
                count as u64 * 4,
            );
        }
        Ok(())
    }

    /// Applies a frame's light settings: each light's direct and indirect factors are
    /// rewritten in the light buffers (when `state` differs from the last one applied) by
    /// copies recorded in the next frame's encoder, before its passes. Nothing is
    /// recompiled, rebuilt or allocated.
    pub fn apply(&mut self, state: &LightState) {
        let fingerprint = state.fingerprint();
        if fingerprint == self.light_state {
            return;
        }
        self.light_state = fingerprint;
        self.light_set.apply(state);
        self.lights_changed = true;
    }

    /// A `width x height` `Rgba32Float` texture usable as [`GpuIsr::encode`]'s output (with
    /// `STORAGE_BINDING | TEXTURE_BINDING | COPY_SRC` usage).
    pub fn output_texture(&self, width: u32, height: u32) -> Result<wgpu::Texture, IsrError> {
        self.ctx.check_texture_size(width, height)?;
        Ok(rgba_texture(&self.ctx, "isr output", width, height))
    }

    /// An intermediate texture of the last recorded frame (`Rgba32Float`), for views of
    /// the pipeline's buffers (the thesis' F-key views): `None` before the first frame.
    /// Its contents are those of the last submitted frame that ran the ISR passes (a
    /// direct-only frame leaves them as they were).
    pub fn intermediate(&self, which: Intermediate) -> Option<&wgpu::Texture> {
        let t = self.targets.as_ref()?;
        Some(match which {
            Intermediate::Senders => &t.senders,
            Intermediate::Radiosity => &t.radiosity,
            Intermediate::Blurred => &t.blurred,
            Intermediate::Upsampled => &t.upsampled,
        })
    }

    /// Uploads the light-space senders `senders` ([`LightSenders::new`], from the scene and
    /// the light set this ISR was made with) for the frames whose settings ask for them
    /// ([`IsrSettings::light_senders`] above 0): the GPU twin of
    /// [`crate::render_cpu_with`]'s, a pass between the ISR + SSAO pass and the blur.
    /// Replaces any given before (a moved light needs new ones); the frame's light state
    /// scales them by their lights' indirect factors, as it does on the CPU. Errors when
    /// their buffer exceeds the device's storage-buffer limit.
    pub fn set_light_senders(&mut self, senders: &LightSenders) -> Result<(), IsrError> {
        let mut data = senders.to_gpu();
        let count = data.len() as u32;
        let texels = (crate::light_senders::DEPTH_RES * crate::light_senders::DEPTH_RES) as usize;
        let maps = senders.visibility && senders.depths.len() == senders.senders.len() * texels;
        let bytes = std::mem::size_of_val(data.as_slice())
            .max(std::mem::size_of_val(senders.depths.as_slice())) as u64;
        let limit = self.ctx.device.limits().max_storage_buffer_binding_size;
        if bytes > limit {
            return Err(IsrError::Budget(scene_core::BudgetExceeded {
                what: "the light-space senders".into(),
                needed: bytes,
                limit,
                unit: "bytes",
                hint: "the device's storage buffer limit; ask for fewer light senders".into(),
            }));
        }
        if data.is_empty() {
            // A binding needs one whole element; the count stays 0 and the pass is skipped.
            data.push(GpuLightSender::default());
        }
        let buffer = self.ctx.buffer_with(
            "isr light senders",
            bytemuck::cast_slice(&data),
            wgpu::BufferUsages::STORAGE,
        );
        let depths: &[f32] = if maps && !senders.depths.is_empty() {
            &senders.depths
        } else {
            &[0.0]
        };
        let depths = self.ctx.buffer_with(
            "isr light sender visibility maps",
            bytemuck::cast_slice(depths),
            wgpu::BufferUsages::STORAGE,
        );
        let mut phases = [[0u32; 4]; 5];
        for (i, offset) in senders.phase_offsets.iter().enumerate() {
            phases[i / 4][i % 4] = *offset;
        }
        self.light_senders = Some(UploadedSenders {
            buffer,
            depths,
            senders: [
                count,
                u32::from(senders.once),
                u32::from(senders.interleaved),
                u32::from(maps),
            ],
            phases,
        });
        // The cached bind groups refer to the previous buffer.
        self.generation += 1;
        Ok(())
    }

    /// The light-space senders a frame with `settings` gathers, `None` when the settings ask
    /// for none (or there is none). Errors when the settings ask for them and none were given, or for their
    /// shadow rays (CPU only).
    fn frame_light_senders(
        &self,
        settings: &IsrSettings,
    ) -> Result<Option<&UploadedSenders>, IsrError> {
        if settings.light_senders == 0 || !settings.indirect {
            return Ok(None);
        }
        if settings.light_sender_shadows {
            return Err(IsrError::InvalidSetting {
                name: "light_sender_shadows",
                value: "true".into(),
                reason: "shadowed light-space senders (a ray per receiver and sender) run on \
                         the CPU only"
                    .into(),
            });
        }
        match &self.light_senders {
            None => Err(IsrError::InvalidSetting {
                name: "light_senders",
                value: settings.light_senders.to_string(),
                reason: "no light-space senders were given: make them with LightSenders::new \
                         and hand them to GpuIsr::set_light_senders"
                    .into(),
            }),
            Some(uploaded) => Ok((uploaded.senders[0] > 0).then_some(uploaded)),
        }
    }

    /// Blocks until the device has finished all submitted work (for timing).
    pub fn wait(&self) -> Result<(), IsrError> {
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Readback(format!("device poll failed: {e}")).into())
    }

    /// Records one frame into `encoder`. The frame's uniforms are copied in by a command of
    /// `encoder` itself, so several frames (views) may be encoded before one submit; the
    /// encoder must be submitted (the staging chunk returns then). Nothing is read back, and
    /// once the textures have been seen no GPU object is created.
    /// `output` must be `full`'s size, `Rgba32Float` or `Rgba16Float`, with
    /// `STORAGE_BINDING` usage; the G-buffers must have [`GpuGBuffer`]'s formats
    /// ([`GpuGBuffer::from_textures`] checks an engine's own textures).
    pub fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &GpuIsrInputs<'_>,
        settings: &IsrSettings,
        output: &wgpu::Texture,
    ) -> Result<(), IsrError> {
        self.record(&mut Recorder::Into(encoder), inputs, settings, output)
    }

    /// Runs one frame and returns the time of each pass (for benchmarks): from timestamp
    /// queries in one submission where the adapter has them, else submitting and waiting
    /// for each pass (slower than [`GpuIsr::encode`]).
    pub fn render_timed(
        &mut self,
        inputs: &GpuIsrInputs<'_>,
        settings: &IsrSettings,
        output: &wgpu::Texture,
    ) -> Result<PassTimings, IsrError> {
        let ctx = self.ctx.clone();
        let mut rec = match PassTimer::new(&ctx, MAX_TIMED_PASSES) {
            Some(timer) => Recorder::Timestamps(
                ctx.device.create_command_encoder(&Default::default()),
                timer,
                Vec::new(),
            ),
            None => Recorder::WallClock(&ctx, PassTimings::default()),
        };
        self.record(&mut rec, inputs, settings, output)?;
        match rec {
            Recorder::Timestamps(mut encoder, timer, stages) => {
                timer.resolve(&mut encoder);
                ctx.queue.submit([encoder.finish()]);
                let mut t = PassTimings {
                    gpu_timestamps: true,
                    ..Default::default()
                };
                for (stage, (_, d)) in stages.iter().zip(timer.read(&ctx)?) {
                    stage.add(&mut t, d);
                }
                Ok(t)
            }
            Recorder::WallClock(_, t) => Ok(t),
            Recorder::Into(_) => Ok(PassTimings::default()),
        }
    }

    /// The CPU twin's way in (tests, the CPU-rendered G-buffer of the `Technique`):
    /// uploads CPU G-buffers (`coarse: None` downsamples `full` on the GPU), runs a timed
    /// frame into an `Rgba32Float` texture and reads the image back.
    pub fn render_gbuffer(
        &mut self,
        full: &GBuffer,
        coarse: Option<&GBuffer>,
        view: &View,
        settings: &IsrSettings,
    ) -> Result<(Image, PassTimings), IsrError> {
        crate::frame::check_gbuffer("full", full)?;
        if let Some(c) = coarse {
            crate::frame::check_gbuffer("coarse", c)?;
        }
        let ctx = self.ctx.clone();
        ctx.validated_with(|| self.run_uploaded(full, coarse, view, settings))
    }

    fn run_uploaded(
        &mut self,
        full: &GBuffer,
        coarse: Option<&GBuffer>,
        view: &View,
        settings: &IsrSettings,
    ) -> Result<(Image, PassTimings), IsrError> {
        let gfull = GpuGBuffer::upload(&self.ctx, full)?;
        let gcoarse = coarse
            .map(|c| GpuGBuffer::upload(&self.ctx, c))
            .transpose()?;
        self.run_read_back(&gfull, gcoarse.as_ref(), view, settings)
    }

    /// One timed frame from G-buffers on the GPU into a new output texture, read back.
    fn run_read_back(
        &mut self,
        full: &GpuGBuffer,
        coarse: Option<&GpuGBuffer>,
        view: &View,
        settings: &IsrSettings,
    ) -> Result<(Image, PassTimings), IsrError> {
        let ctx = self.ctx.clone();
        let output = rgba_texture(&ctx, "isr output", full.width, full.height);
        let inputs = GpuIsrInputs { full, coarse, view };
        let timings = self.render_timed(&inputs, settings, &output)?;
        let image = ctx.read_texture_image(&output)?;
        Ok((image, timings))
    }

    /// One frame from a G-buffer already on the GPU (a GPU rasteriser's, or the host's
    /// converted by [`scene_core::gpu::HostGBufferPass`]), the coarse buffer made on the GPU,
    /// the image read back: what the GPU [`crate::IsrTechnique`] runs when its renderer
    /// keeps the G-buffer on the GPU, with no read-back and upload of the G-buffer.
    pub fn render_gpu_gbuffer(
        &mut self,
        full: &GpuGBuffer,
        view: &View,
        settings: &IsrSettings,
    ) -> Result<(Image, PassTimings), IsrError> {
        let ctx = self.ctx.clone();
        ctx.validated_with(|| self.run_read_back(full, None, view, settings))
    }

    fn check_output(&self, output: &wgpu::Texture, full: &GpuGBuffer) -> Result<(), IsrError> {
        if (output.width(), output.height()) != (full.width, full.height) {
            return Err(IsrError::SizeMismatch(format!(
                "output texture {}x{}, G-buffer {}x{}",
                output.width(),
                output.height(),
                full.width,
                full.height
            )));
        }
        // Format and usage: the frame contract's target check.
        Ok(scene_core::gpu::check_frame_target(
            output,
            full.width,
            full.height,
        )?)
    }

    fn ensure_targets(
        &mut self,
        full: (u32, u32),
        coarse: (u32, u32),
        own_coarse: bool,
    ) -> Result<(), IsrError> {
        let fits = self.targets.as_ref().is_some_and(|t| {
            t.full == full && t.coarse == coarse && t.coarse_gbuffer.is_some() == own_coarse
        });
        if fits {
            return Ok(());
        }
        let ctx = &self.ctx;
        let (cw, ch) = coarse;
        self.generation += 1;
        self.targets = Some(Targets {
            full,
            coarse,
            coarse_gbuffer: if own_coarse {
                Some(GpuGBuffer::new(ctx, cw, ch)?)
            } else {
                None
            },
            senders: rgba_texture(ctx, "isr senders", cw, ch),
            screen_radiosity: rgba_texture(ctx, "isr screen-space radiosity", cw, ch),
            radiosity: rgba_texture(ctx, "isr radiosity", cw, ch),
            tmp: rgba_texture(ctx, "isr blur tmp", cw, ch),
            blurred: rgba_texture(ctx, "isr blurred", cw, ch),
            upsampled: rgba_texture(ctx, "isr upsampled", full.0, full.1),
        });
        Ok(())
    }

    fn record(
        &mut self,
        rec: &mut Recorder<'_>,
        inputs: &GpuIsrInputs<'_>,
        settings: &IsrSettings,
        output: &wgpu::Texture,
    ) -> Result<(), IsrError> {
        settings.validate(self.extent)?;
        let light_senders = self
            .frame_light_senders(settings)?
            .map(|u| (u.senders, u.phases));
        let full = inputs.full;
        self.check_output(output, full)?;
        let full_size = (full.width, full.height);
        let coarse_size = match inputs.coarse {
            Some(c) => (c.width, c.height),
            None => coarse_size(full.width, full.height),
        };
        self.ensure_targets(full_size, coarse_size, inputs.coarse.is_none())?;
        if self
            .pattern
            .as_ref()
            .is_none_or(|(n, _)| *n != settings.samples)
        {
            let data = SamplePattern::new(settings.samples).to_gpu();
            self.generation += 1;
            self.pattern = Some((
                settings.samples,
                self.ctx.buffer_with(
                    "isr sample pattern",
                    bytemuck::cast_slice(&data),
                    wgpu::BufferUsages::STORAGE,
                ),
            ));
        }
        let screen = Screen::new(inputs.view);
        let mut globals = Globals::new(&screen, &self.light_set, settings, full_size, coarse_size);
        globals.view_proj = inputs.view.view_projection().to_cols_array_2d();
        if let Some((senders, phases)) = light_senders {
            globals.senders = senders;
            globals.sender_phases = phases;
        }
        // This frame's uniforms, copied into the one globals buffer by a command of the
        // frame's own encoder (so a second view encoded before the submit reads its own).
        rec.upload(
            &self.writer,
            &self.ctx,
            &self.globals,
            bytemuck::bytes_of(&globals),
        );
        if std::mem::take(&mut self.lights_changed) {
            let lights = gpu_lights(&self.light_set);
            rec.upload(
                &self.writer,
                &self.ctx,
                &self.lights,
                bytemuck::cast_slice(&lights),
            );
            let table = gpu_emitters(&self.light_set);
            rec.upload(
                &self.writer,
                &self.ctx,
                &self.emitters,
                bytemuck::cast_slice(&table),
            );
        }
        let run_isr = !settings.is_direct_only() && self.light_set.has_light();
        let key = BindKey {
            full: textures_of(full),
            coarse: inputs.coarse.map(textures_of),
            output: output.clone(),
            generation: self.generation,
            downsample: settings.downsample,
            run_isr,
            lit: settings.indirect && settings.sender == Sender::Lit,
            light_senders: run_isr && light_senders.is_some(),
            blur: settings.blur_radius > 0,
            half: key_half(output),
        };
        if !self.bound.is_for(&key) {
            self.bound.clear();
            let bound = self.bind(inputs, settings, output, &key)?;
            self.bound.set(key, bound);
        }
        let (Some(t), Some(b)) = (self.targets.as_ref(), self.bound.value()) else {
            return Err(IsrError::SizeMismatch("no intermediate textures".into()));
        };
        let coarse: &GpuGBuffer = match (inputs.coarse, t.coarse_gbuffer.as_ref()) {
            (Some(c), _) => c,
            (None, Some(own)) => {
                let mut result = Ok(());
                if let Some(bg) = &b.downsample {
                    rec.pass(Stage::Downsample, |e, ts| {
                        result = self
                            .downsample
                            .encode_bound(e, bg, own, settings.downsample, ts);
                    });
                }
                result?;
                own
            }
            (None, None) => return Err(IsrError::SizeMismatch("no coarse buffer".into())),
        };
        let device = &self.ctx.device;
        if let Some(bg) = &b.senders {
            let lp = self.lighting.pipeline(device, Variant::Senders);
            rec.pass(Stage::Senders, |e, ts| {
                lp.dispatch(e, bg, coarse.width, coarse.height, ts)
            });
        }
        if let Some(bg) = &b.radiosity {
            rec.pass(Stage::Radiosity, |e, ts| {
                self.radiosity
                    .pipeline
                    .dispatch(e, bg, coarse.width, coarse.height, ts)
            });
        }
        if let Some(bg) = &b.light_senders {
            rec.pass(Stage::LightSenders, |e, ts| {
                self.light_senders_pass
                    .pipeline
                    .dispatch(e, bg, coarse.width, coarse.height, ts)
            });
        }
        if let Some([h, v]) = &b.blur {
            rec.pass(Stage::Blur, |e, ts| {
                self.blur
                    .pipeline(true)
                    .dispatch(e, h, coarse.width, coarse.height, ts)
            });
            rec.pass(Stage::Blur, |e, ts| {
                self.blur
                    .pipeline(false)
                    .dispatch(e, v, coarse.width, coarse.height, ts)
            });
        }
        if let Some(bg) = &b.upsample {
            rec.pass(Stage::Upsample, |e, ts| {
                self.upsample
                    .pipeline
                    .dispatch(e, bg, full.width, full.height, ts)
            });
        }
        let lighting_pass = self.lighting.pipeline(
            device,
            Variant::Compose {
                with_isr: run_isr,
                half: key_half(output),
            },
        );
        let bg = &b.compose;
        rec.pass(Stage::Lighting, |e, ts| {
            lighting_pass.dispatch(e, bg, full.width, full.height, ts)
        });
        rec.finish(&self.writer);
        Ok(())
    }

    /// The bind groups of a frame with `key` (made when the inputs change; a steady stream
    /// of frames on the same textures reuses them and creates no GPU object).
    fn bind(
        &self,
        inputs: &GpuIsrInputs<'_>,
        settings: &IsrSettings,
        output: &wgpu::Texture,
        key: &BindKey,
    ) -> Result<Bound, IsrError> {
        let device = &self.ctx.device;
        let Some(t) = self.targets.as_ref() else {
            return Err(IsrError::SizeMismatch("no intermediate textures".into()));
        };
        let Some((_, pattern)) = self.pattern.as_ref() else {
            return Err(IsrError::SizeMismatch("no sample pattern".into()));
        };
        let full = inputs.full;
        let (coarse, downsample) = match (inputs.coarse, t.coarse_gbuffer.as_ref()) {
            (Some(c), _) => (c, None),
            (None, Some(own)) => (
                own,
                Some(self.downsample.bind(full, own, settings.downsample)?),
            ),
            (None, None) => return Err(IsrError::SizeMismatch("no coarse buffer".into())),
        };
        let light_buffers = LightBuffers {
            lights: &self.lights,
            shadow_texels: &self.shadow_texels,
            emitter_of: &self.emitter_of,
            emitters: &self.emitters,
        };
        let globals = &self.globals;
        let (mut senders, mut radiosity, mut blur, mut upsample) = (None, None, None, None);
        let mut light_senders = None;
        if key.run_isr {
            if key.lit {
                let lp = self.lighting.pipeline(device, Variant::Senders);
                senders = Some(bind_lighting(
                    lp,
                    device,
                    globals,
                    coarse,
                    &self.dummy,
                    &light_buffers,
                    &view_of(&t.senders),
                ));
            }
            let senders_tex = if key.lit { &t.senders } else { &self.dummy };
            // With light-space senders the screen-space pass writes its own texture and
            // the light-space pass adds to it into `radiosity`.
            let screen_out = match self.light_senders.as_ref().filter(|_| key.light_senders) {
                Some(UploadedSenders { buffer, depths, .. }) => {
                    light_senders = Some(self.light_senders_pass.bind(
                        device,
                        globals,
                        buffer,
                        depths,
                        coarse,
                        &self.lights,
                        &t.screen_radiosity,
                        &t.radiosity,
                    ));
                    &t.screen_radiosity
                }
                None => &t.radiosity,
            };
            radiosity = Some(self.radiosity.bind(
                device,
                globals,
                pattern,
                coarse,
                senders_tex,
                screen_out,
            ));
            let blurred = if key.blur {
                blur = Some([
                    self.blur
                        .bind(device, true, globals, coarse, &t.radiosity, &t.tmp),
                    self.blur
                        .bind(device, false, globals, coarse, &t.tmp, &t.blurred),
                ]);
                &t.blurred
            } else {
                &t.radiosity
            };
            upsample =
                Some(
                    self.upsample
                        .bind(device, globals, full, coarse, blurred, &t.upsampled),
                );
        }
        let isr_tex = if key.run_isr {
            &t.upsampled
        } else {
            &self.dummy
        };
        let compose_pass = self.lighting.pipeline(
            device,
            Variant::Compose {
                with_isr: key.run_isr,
                half: key.half,
            },
        );
        let compose = bind_lighting(
            compose_pass,
            device,
            globals,
            full,
            isr_tex,
            &light_buffers,
            &view_of(output),
        );
        Ok(Bound {
            downsample,
            senders,
            radiosity,
            light_senders,
            blur,
            upsample,
            compose,
        })
    }
}

fn key_half(output: &wgpu::Texture) -> bool {
    output.format() == wgpu::TextureFormat::Rgba16Float
}
