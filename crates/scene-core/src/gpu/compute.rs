//! The one compute-pipeline helper of the toolkit: a [`ComputePass`] is a WGSL module's
//! `main` entry point with its bind group layout, compiled with values for the shader's
//! pipeline-overridable constants (`override` declarations: pass options are chosen per
//! pipeline, not by indexing parameter buffers or editing source text), bound and
//! dispatched over an image in 8 x 8 workgroups. Every compute shader of scene-core, the
//! gbuffer crate and ISR is set up through it.

use super::GpuError;
use super::shader::ShaderPass;

/// Workgroup edge of every image-space compute shader (`@workgroup_size(8, 8, 1)`).
pub const WORKGROUP: u32 = 8;

/// A compute pipeline (entry point `main`) and its bind group layout.
#[derive(Clone, Debug)]
pub struct ComputePass {
    /// The pipeline.
    pub pipeline: wgpu::ComputePipeline,
    /// Its only bind group's layout (group 0).
    pub layout: wgpu::BindGroupLayout,
}

impl ComputePass {
    /// Composes `pass` ([`ShaderPass::create_module`], an error if it does not compose) and
    /// compiles it with `constants` (name and value of each `override` to set) and
    /// `entries` as group 0. wgpu reports its own errors through the device's error scopes:
    /// wrap the call in [`crate::gpu::GpuContext::validated`] to receive them as values.
    pub fn new(
        device: &wgpu::Device,
        label: &str,
        pass: &ShaderPass,
        entries: &[wgpu::BindGroupLayoutEntry],
        constants: &[(&str, f64)],
    ) -> Result<Self, GpuError> {
        let module = pass.create_module(device)?;
        Ok(Self::from_module(
            device, label, &module, entries, constants,
        ))
    }

    /// The same from an already compiled module (several pipelines of one module that
    /// differ in their constants share it).
    pub fn from_module(
        device: &wgpu::Device,
        label: &str,
        module: &wgpu::ShaderModule,
        entries: &[wgpu::BindGroupLayoutEntry],
        constants: &[(&str, f64)],
    ) -> Self {
        Self::from_entry_point(device, label, module, "main", entries, constants)
    }

    /// The same with another entry point than `main` (one module holding several passes).
    pub fn from_entry_point(
        device: &wgpu::Device,
        label: &str,
        module: &wgpu::ShaderModule,
        entry_point: &str,
        entries: &[wgpu::BindGroupLayoutEntry],
        constants: &[(&str, f64)],
    ) -> Self {
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries,
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: Some(&pipeline_layout),
            module,
            entry_point: Some(entry_point),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants,
                ..Default::default()
            },
            cache: None,
        });
        Self { pipeline, layout }
    }

    /// A bind group with `resources[i]` at binding `i`.
    pub fn bind(
        &self,
        device: &wgpu::Device,
        resources: &[wgpu::BindingResource<'_>],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry<'_>> = resources
            .iter()
            .enumerate()
            .map(|(i, r)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: r.clone(),
            })
            .collect();
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &self.layout,
            entries: &entries,
        })
    }

    /// A bind group with `buffers` (whole) at bindings `0..`, then a default view of each of
    /// `textures` at the bindings after them.
    pub fn bind_buffers_then_textures(
        &self,
        device: &wgpu::Device,
        buffers: &[&wgpu::Buffer],
        textures: &[&wgpu::Texture],
    ) -> wgpu::BindGroup {
        let views: Vec<wgpu::TextureView> = textures
            .iter()
            .map(|t| t.create_view(&Default::default()))
            .collect();
        let mut res: Vec<wgpu::BindingResource<'_>> =
            buffers.iter().map(|b| b.as_entire_binding()).collect();
        res.extend(views.iter().map(wgpu::BindingResource::TextureView));
        self.bind(device, &res)
    }

    /// Records one compute pass dispatching enough workgroups to cover `width x height`
    /// invocations, with optional timestamp writes at its start and end.
    pub fn dispatch(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        bind_group: &wgpu::BindGroup,
        width: u32,
        height: u32,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: None,
            timestamp_writes: timestamps,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        pass.dispatch_workgroups(width.div_ceil(WORKGROUP), height.div_ceil(WORKGROUP), 1);
    }
}

/// GPU pass timings from timestamp queries: each timed pass writes a timestamp at its start
/// and end ([`PassTimer::writes`] gives the [`wgpu::ComputePassTimestampWrites`]); after the
/// work is recorded, [`PassTimer::resolve`] copies them into a buffer and
/// [`PassTimer::read`] returns each pass' duration. Only where the adapter has
/// [`wgpu::Features::TIMESTAMP_QUERY`] and is a real GPU ([`PassTimer::new`] returns `None`
/// elsewhere; time with the wall clock there). CPU adapters are left out because their
/// timestamps do not time the work: on lavapipe (llvmpipe, LLVM 15) passes that take 20 to
/// 200 ms of wall-clock time read 0.02 to 0.1 ms.
#[derive(Debug)]
pub struct PassTimer {
    set: wgpu::QuerySet,
    resolved: wgpu::Buffer,
    capacity: u32,
    labels: Vec<&'static str>,
    period_ns: f32,
}

impl PassTimer {
    /// A timer for up to `passes` passes, or `None` without timestamp queries or on a CPU
    /// adapter.
    pub fn new(ctx: &super::GpuContext, passes: u32) -> Option<Self> {
        if !ctx
            .device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
            || ctx.adapter_info().device_type == wgpu::DeviceType::Cpu
            || passes == 0
        {
            return None;
        }
        let count = 2 * passes;
        let set = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("pass timer"),
            ty: wgpu::QueryType::Timestamp,
            count,
        });
        let resolved = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("pass timer"),
            size: count as u64 * 8,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        Some(Self {
            set,
            resolved,
            capacity: passes,
            labels: Vec::new(),
            period_ns: ctx.queue.get_timestamp_period(),
        })
    }

    /// The timestamp writes of the next pass, labelled `label` (`None` once the capacity is
    /// used up: that pass goes untimed).
    pub fn writes(&mut self, label: &'static str) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        let k = self.labels.len() as u32;
        if k >= self.capacity {
            return None;
        }
        self.labels.push(label);
        Some(wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(2 * k),
            end_of_pass_write_index: Some(2 * k + 1),
        })
    }

    /// Records the copy of the timestamps written so far into the timer's buffer.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        let n = 2 * self.labels.len() as u32;
        if n > 0 {
            encoder.resolve_query_set(&self.set, 0..n, &self.resolved, 0);
        }
    }

    /// Waits for the GPU and returns each timed pass' label and duration, in recording
    /// order (after the encoder holding [`PassTimer::resolve`] was submitted).
    pub fn read(
        &self,
        ctx: &super::GpuContext,
    ) -> Result<Vec<(&'static str, std::time::Duration)>, super::GpuError> {
        let ticks: Vec<u64> = ctx.read_buffer_as(&self.resolved)?;
        Ok(self
            .labels
            .iter()
            .enumerate()
            .map(|(k, label)| {
                let (a, b) = (ticks[2 * k], ticks[2 * k + 1]);
                let ns = b.saturating_sub(a) as f64 * self.period_ns as f64;
                (*label, std::time::Duration::from_nanos(ns as u64))
            })
            .collect())
    }
}
