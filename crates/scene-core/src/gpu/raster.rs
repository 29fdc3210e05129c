//! The toolkit's raster passes in one shape: a triangle list drawn two-sided (no culling)
//! with a `Depth32Float` depth test (`Less`, written), the vertex stage `vs_main` and the
//! fragment stage `fs_main` of one module, one bind group. The G-buffer pass
//! (`gbuffer::GpuRasterizer`), the id raster (`relight_pr::element_ids::TriangleIdPass`) and the shadow-map
//! faces (`crate::shadowed_lights::gpu_maps::ShadowMapPass`) differ only in their vertex
//! buffers and colour targets.

/// The depth format of every raster pass.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// A raster pipeline of the shape above over the bind group `layout`.
pub fn depth_tested_pipeline(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    module: &wgpu::ShaderModule,
    buffers: &[Option<wgpu::VertexBufferLayout<'_>>],
    targets: &[Option<wgpu::ColorTargetState>],
) -> wgpu::RenderPipeline {
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers,
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            front_face: wgpu::FrontFace::Ccw,
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// A render pass over colour `targets`, each cleared to its colour and stored, and a
/// [`DEPTH_FORMAT`] attachment cleared to 1 and then stored or discarded (`depth_store`):
/// the pass every raster pipeline of the shape above draws in.
pub fn depth_tested_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    targets: &[(&wgpu::TextureView, wgpu::Color)],
    depth: &wgpu::TextureView,
    depth_store: wgpu::StoreOp,
) -> wgpu::RenderPass<'e> {
    let attachments: Vec<Option<wgpu::RenderPassColorAttachment<'_>>> = targets
        .iter()
        .map(|&(view, clear)| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(clear),
                    store: wgpu::StoreOp::Store,
                },
            })
        })
        .collect();
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &attachments,
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: depth,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(1.0),
                store: depth_store,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

/// A [`depth_tested_pass`] of one colour target cleared to `(clear, 0, 0, 0)` (a
/// single-channel value: an id, a depth) whose depth is discarded after: the one-value
/// raster passes (the id raster, the shadow-map faces).
pub fn one_target_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    colour: &wgpu::TextureView,
    clear: f64,
    depth: &wgpu::TextureView,
) -> wgpu::RenderPass<'e> {
    let clear = wgpu::Color {
        r: clear,
        g: 0.0,
        b: 0.0,
        a: 0.0,
    };
    depth_tested_pass(
        encoder,
        label,
        &[(colour, clear)],
        depth,
        wgpu::StoreOp::Discard,
    )
}
