//! ISR's GPU passes, one section each: the WGSL a pass runs (`shaders/isr/`, composed by
//! scene-core's shader composer: `common.wgsl` is the module `isr::common`, importing
//! `scene_core::reconstruct`; the lighting pass imports scene-core's light set
//! (`scene_core::light_set`) and shadow maps (`scene_core::shadow`), the WGSL twins of
//! [`crate::light_set`] and [`crate::shadow`]), its pipeline and its bind groups.
//! [`crate::gpu::GpuIsr`] records them in order; each pass's CPU twin, with the paper's
//! equations, is the module named in its doc comment.

use scene_core::gpu::layout::{
    self, storage_buffer as storage_buffer_entry, storage_texture as storage_texture_entry,
    uniform as uniform_entry,
};
use scene_core::gpu::shader::{LIMITS, RECONSTRUCT, ShaderPass, Wgsl};
use scene_core::wgsl_file;

/// Globals, flags and view helpers of every ISR pass (`isr::common`).
pub const COMMON: Wgsl = wgsl_file!("isr", "common.wgsl");
pub use scene_core::shadowed_lights::gpu::{LIGHT_SET, SHADOW};

/// What every ISR pass may import.
const LIBRARY: &[Wgsl] = &[RECONSTRUCT, LIMITS, COMMON, LIGHT_SET, SHADOW];

/// The lighting pass writing `Rgba32Float` (eq. 29).
pub const LIGHTING: ShaderPass =
    ShaderPass::new("isr/lighting", wgsl_file!("isr", "lighting.wgsl"), LIBRARY);
/// The lighting pass writing `Rgba16Float` (WGSL cannot make a storage format overridable:
/// the variant is composed with the shader def `OUTPUT_RGBA16F`).
pub const LIGHTING_RGBA16F: ShaderPass =
    LIGHTING.with_defs("isr/lighting (rgba16f)", &["OUTPUT_RGBA16F"]);
/// The ISR + SSAO pass on the coarse buffers.
pub const RADIOSITY: ShaderPass = ShaderPass::new(
    "isr/radiosity",
    wgsl_file!("isr", "radiosity.wgsl"),
    LIBRARY,
);
/// The light-space senders' gather after the ISR + SSAO pass (`crate::light_senders`).
pub const LIGHT_SENDERS: ShaderPass = ShaderPass::new(
    "isr/light_senders",
    wgsl_file!("isr", "light_senders.wgsl"),
    LIBRARY,
);
/// One direction of the separable blur.
pub const BLUR: ShaderPass = ShaderPass::new("isr/blur", wgsl_file!("isr", "blur.wgsl"), LIBRARY);
/// Bilateral upsampling of the blurred coarse buffer.
pub const UPSAMPLE: ShaderPass =
    ShaderPass::new("isr/upsample", wgsl_file!("isr", "upsample.wgsl"), LIBRARY);

/// Every ISR shader pass, as `cargo xtask shaders` validates them.
pub const SHADER_PASSES: &[ShaderPass] = &[
    LIGHTING,
    LIGHTING_RGBA16F,
    RADIOSITY,
    LIGHT_SENDERS,
    BLUR,
    UPSAMPLE,
];

// ---- bind-group layout entries ----

/// A sampled (read with `textureLoad`) 2D texture binding: `u32` or non-filterable float.
fn texture_entry(binding: u32, uint: bool) -> wgpu::BindGroupLayoutEntry {
    if uint {
        layout::texture(binding, wgpu::TextureSampleType::Uint)
    } else {
        layout::float_texture(binding)
    }
}

// ---- the lighting pass ----

/// The light set's storage buffers the lighting pass reads.
pub(crate) struct LightBuffers<'a> {
    pub lights: &'a wgpu::Buffer,
    pub shadow_texels: &'a wgpu::Buffer,
    pub emitter_of: &'a wgpu::Buffer,
    pub emitters: &'a wgpu::Buffer,
}

/// Which pipeline of the pass: its `MODE` and `HAS_ISR` constants and output format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Variant {
    /// The `Lit` senders on the coarse buffer (`Rgba32Float`).
    Senders,
    /// Eq. 29 into `format`, with or without the upsampled ISR/SSAO buffer.
    Compose { with_isr: bool, half: bool },
}

impl Variant {
    fn slot(self) -> usize {
        match self {
            Variant::Senders => 0,
            Variant::Compose { with_isr, half } => {
                1 + usize::from(with_isr) + 2 * usize::from(half)
            }
        }
    }
}

/// The lighting pass (`crate::lighting`, eq. 29): one pipeline per [`Variant`], compiled when first used (the two output
/// formats share nothing but their source).
pub(crate) struct LightingPass {
    modules: [wgpu::ShaderModule; 2],
    pipelines: [std::sync::OnceLock<scene_core::gpu::ComputePass>; 5],
}

impl LightingPass {
    pub(crate) fn new(device: &wgpu::Device) -> Result<Self, scene_core::gpu::GpuError> {
        Ok(Self {
            modules: [
                LIGHTING.create_module(device)?,
                LIGHTING_RGBA16F.create_module(device)?,
            ],
            pipelines: Default::default(),
        })
    }

    /// The pipeline of `variant`.
    pub(crate) fn pipeline(
        &self,
        device: &wgpu::Device,
        variant: Variant,
    ) -> &scene_core::gpu::ComputePass {
        self.pipelines[variant.slot()].get_or_init(|| {
            let (mode, with_isr, half) = match variant {
                Variant::Senders => (0.0, false, false),
                Variant::Compose { with_isr, half } => (1.0, with_isr, half),
            };
            let format = if half {
                wgpu::TextureFormat::Rgba16Float
            } else {
                wgpu::TextureFormat::Rgba32Float
            };
            scene_core::gpu::ComputePass::from_module(
                device,
                "isr lighting",
                &self.modules[usize::from(half)],
                &[
                    uniform_entry(0),
                    texture_entry(1, false),
                    texture_entry(2, false),
                    texture_entry(3, false),
                    texture_entry(4, true),
                    texture_entry(5, false),
                    storage_buffer_entry(6),
                    storage_buffer_entry(7),
                    storage_buffer_entry(8),
                    storage_buffer_entry(9),
                    storage_texture_entry(10, format),
                ],
                &[
                    ("MODE", mode),
                    ("HAS_ISR", if with_isr { 1.0 } else { 0.0 }),
                ],
            )
        })
    }
}

/// A bind group of `pipeline` over G-buffer `g`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn bind_lighting(
    pipeline: &scene_core::gpu::ComputePass,
    device: &wgpu::Device,
    globals: &wgpu::Buffer,
    g: &scene_core::gpu::GpuGBuffer,
    isr: &wgpu::Texture,
    lights: &LightBuffers<'_>,
    out: &wgpu::TextureView,
) -> wgpu::BindGroup {
    let v = |t: &wgpu::Texture| t.create_view(&Default::default());
    let views = [
        v(&g.albedo),
        v(&g.normal),
        v(&g.depth),
        v(&g.triangle_id),
        v(isr),
    ];
    let mut res = vec![globals.as_entire_binding()];
    res.extend(views.iter().map(wgpu::BindingResource::TextureView));
    res.extend([
        lights.lights.as_entire_binding(),
        lights.shadow_texels.as_entire_binding(),
        lights.emitter_of.as_entire_binding(),
        lights.emitters.as_entire_binding(),
        wgpu::BindingResource::TextureView(out),
    ]);
    pipeline.bind(device, &res)
}

// ---- the ISR + SSAO pass ----

/// The ISR + SSAO pass (`crate::radiosity`, eqs. 25-26).
pub(crate) struct RadiosityPass {
    pub pipeline: scene_core::gpu::ComputePass,
}

impl RadiosityPass {
    pub(crate) fn new(device: &wgpu::Device) -> Result<Self, scene_core::gpu::GpuError> {
        Ok(Self {
            pipeline: scene_core::gpu::ComputePass::new(
                device,
                "isr radiosity",
                &RADIOSITY,
                &[
                    uniform_entry(0),
                    storage_buffer_entry(1),
                    texture_entry(2, false),
                    texture_entry(3, false),
                    texture_entry(4, false),
                    texture_entry(5, true),
                    texture_entry(6, false),
                    storage_texture_entry(7, wgpu::TextureFormat::Rgba32Float),
                ],
                &[],
            )?,
        })
    }

    pub(crate) fn bind(
        &self,
        device: &wgpu::Device,
        globals: &wgpu::Buffer,
        pattern: &wgpu::Buffer,
        coarse: &scene_core::gpu::GpuGBuffer,
        senders: &wgpu::Texture,
        out: &wgpu::Texture,
    ) -> wgpu::BindGroup {
        self.pipeline.bind_buffers_then_textures(
            device,
            &[globals, pattern],
            &[
                &coarse.albedo,
                &coarse.normal,
                &coarse.depth,
                &coarse.triangle_id,
                senders,
                out,
            ],
        )
    }
}

// ---- the light-space senders ----

/// The light-space senders' gather (`crate::light_senders`): reads the ISR + SSAO pass'
/// output and writes it with the senders' one bounce added.
pub(crate) struct LightSendersPass {
    pub pipeline: scene_core::gpu::ComputePass,
}

impl LightSendersPass {
    pub(crate) fn new(device: &wgpu::Device) -> Result<Self, scene_core::gpu::GpuError> {
        Ok(Self {
            pipeline: scene_core::gpu::ComputePass::new(
                device,
                "isr light senders",
                &LIGHT_SENDERS,
                &[
                    uniform_entry(0),
                    storage_buffer_entry(1),
                    texture_entry(2, false),
                    texture_entry(3, false),
                    texture_entry(4, false),
                    texture_entry(5, true),
                    // The light set's lights, where `scene_core::light_set` declares them.
                    storage_buffer_entry(6),
                    texture_entry(7, false),
                    storage_texture_entry(10, wgpu::TextureFormat::Rgba32Float),
                    storage_buffer_entry(11),
                ],
                &[],
            )?,
        })
    }

    /// The bind group over the coarse G-buffer `coarse`, the senders (`GpuLightSender`s)
    /// and their visibility maps `depths`,
    /// the light set's `lights`, the ISR + SSAO output `radiosity` and the output `out`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn bind(
        &self,
        device: &wgpu::Device,
        globals: &wgpu::Buffer,
        senders: &wgpu::Buffer,
        depths: &wgpu::Buffer,
        coarse: &scene_core::gpu::GpuGBuffer,
        lights: &wgpu::Buffer,
        radiosity: &wgpu::Texture,
        out: &wgpu::Texture,
    ) -> wgpu::BindGroup {
        let v = |t: &wgpu::Texture| t.create_view(&Default::default());
        let views = [
            v(&coarse.albedo),
            v(&coarse.normal),
            v(&coarse.depth),
            v(&coarse.triangle_id),
            v(radiosity),
            v(out),
        ];
        let resources = [
            (0, globals.as_entire_binding()),
            (1, senders.as_entire_binding()),
            (2, wgpu::BindingResource::TextureView(&views[0])),
            (3, wgpu::BindingResource::TextureView(&views[1])),
            (4, wgpu::BindingResource::TextureView(&views[2])),
            (5, wgpu::BindingResource::TextureView(&views[3])),
            (6, lights.as_entire_binding()),
            (7, wgpu::BindingResource::TextureView(&views[4])),
            (10, wgpu::BindingResource::TextureView(&views[5])),
            (11, depths.as_entire_binding()),
        ];
        let entries: Vec<wgpu::BindGroupEntry<'_>> = resources
            .into_iter()
            .map(|(binding, resource)| wgpu::BindGroupEntry { binding, resource })
            .collect();
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("isr light senders"),
            layout: &self.pipeline.layout,
            entries: &entries,
        })
    }
}

// ---- the blur ----

/// The separable blur (`crate::blur`): one pipeline per direction (the shader's `HORIZONTAL` constant) over one
/// compiled module.
pub(crate) struct BlurPass {
    /// Horizontal, vertical.
    pub pipelines: [scene_core::gpu::ComputePass; 2],
}

impl BlurPass {
    pub(crate) fn new(device: &wgpu::Device) -> Result<Self, scene_core::gpu::GpuError> {
        let module = BLUR.create_module(device)?;
        let entries = [
            uniform_entry(0),
            texture_entry(1, false),
            texture_entry(2, false),
            texture_entry(3, true),
            texture_entry(4, false),
            storage_texture_entry(5, wgpu::TextureFormat::Rgba32Float),
        ];
        let make = |horizontal: bool| {
            scene_core::gpu::ComputePass::from_module(
                device,
                "isr blur",
                &module,
                &entries,
                &[("HORIZONTAL", if horizontal { 1.0 } else { 0.0 })],
            )
        };
        Ok(Self {
            pipelines: [make(true), make(false)],
        })
    }

    /// A bind group of the `horizontal` (else vertical) pipeline.
    pub(crate) fn bind(
        &self,
        device: &wgpu::Device,
        horizontal: bool,
        globals: &wgpu::Buffer,
        coarse: &scene_core::gpu::GpuGBuffer,
        input: &wgpu::Texture,
        out: &wgpu::Texture,
    ) -> wgpu::BindGroup {
        self.pipeline(horizontal).bind_buffers_then_textures(
            device,
            &[globals],
            &[
                &coarse.normal,
                &coarse.depth,
                &coarse.triangle_id,
                input,
                out,
            ],
        )
    }

    /// The pipeline of one direction.
    pub(crate) fn pipeline(&self, horizontal: bool) -> &scene_core::gpu::ComputePass {
        &self.pipelines[usize::from(!horizontal)]
    }
}

// ---- the upsampling ----

/// The bilateral upsampling (`crate::upsample`).
pub(crate) struct UpsamplePass {
    pub pipeline: scene_core::gpu::ComputePass,
}

impl UpsamplePass {
    pub(crate) fn new(device: &wgpu::Device) -> Result<Self, scene_core::gpu::GpuError> {
        Ok(Self {
            pipeline: scene_core::gpu::ComputePass::new(
                device,
                "isr upsample",
                &UPSAMPLE,
                &[
                    uniform_entry(0),
                    texture_entry(1, false),
                    texture_entry(2, false),
                    texture_entry(3, true),
                    texture_entry(4, false),
                    texture_entry(5, false),
                    texture_entry(6, true),
                    texture_entry(7, false),
                    storage_texture_entry(8, wgpu::TextureFormat::Rgba32Float),
                ],
                &[],
            )?,
        })
    }

    pub(crate) fn bind(
        &self,
        device: &wgpu::Device,
        globals: &wgpu::Buffer,
        full: &scene_core::gpu::GpuGBuffer,
        coarse: &scene_core::gpu::GpuGBuffer,
        values: &wgpu::Texture,
        out: &wgpu::Texture,
    ) -> wgpu::BindGroup {
        self.pipeline.bind_buffers_then_textures(
            device,
            &[globals],
            &[
                &full.normal,
                &full.depth,
                &full.triangle_id,
                &coarse.normal,
                &coarse.depth,
                &coarse.triangle_id,
                values,
                out,
            ],
        )
    }
}
