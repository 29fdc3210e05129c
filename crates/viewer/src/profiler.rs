//! Timing the stages of the viewer's GPU frame: [`StageProfiler`] (timestamps between the
//! stages of one command encoder, or each stage submitted and waited for where the adapter
//! cannot time inside an encoder), reporting `(label, Duration)` lists, the shape of
//! [`scene_core::StageTimings`]. (In `scene_core::gpu::timing` until 2026-11-27; the
//! methods' per-pass timer, `scene_core::gpu::PassTimer`, stays in scene-core.)

use std::time::{Duration, Instant};

use scene_core::gpu::{GpuContext, GpuError};

/// GPU timestamps written between the stages of a frame (inside one command encoder).
struct Timestamps {
    set: wgpu::QuerySet,
    resolved: wgpu::Buffer,
    written: u32,
    period_ns: f32,
}

/// Most stages a frame is timed in (the viewer's: two modes, compose, the present pass, and
/// spares).
const MAX_STAGES: u32 = 16;

/// Per-stage times of a frame, when `on`. Where the device can write timestamps inside a
/// command encoder (`TIMESTAMP_QUERY_INSIDE_ENCODERS`) and is not a CPU adapter (whose
/// timestamps do not time the work), each stage ends with a GPU timestamp and the frame is
/// submitted as usual; elsewhere each stage is submitted on its own and waited for, giving
/// wall-clock times of the work (slower, but true on any adapter, lavapipe included).
pub struct StageProfiler<'a> {
    ctx: &'a GpuContext,
    on: bool,
    last: Instant,
    timestamps: Option<Timestamps>,
    labels: Vec<&'static str>,
    /// Each stage's label and time, in order (GPU stages filled in by
    /// [`StageProfiler::read_gpu`]).
    pub times: Vec<(&'static str, Duration)>,
}

impl<'a> StageProfiler<'a> {
    /// A profiler that times stages when `on`; `allow_cpu` lets a CPU adapter use
    /// timestamps too (for tests of the mechanism only).
    pub fn new(ctx: &'a GpuContext, on: bool, allow_cpu: bool) -> Self {
        let wanted =
            wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS;
        let usable = ctx.device.features().contains(wanted)
            && (allow_cpu || ctx.adapter_info().device_type != wgpu::DeviceType::Cpu);
        let timestamps = (on && usable).then(|| Timestamps {
            set: ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("stage profiler"),
                ty: wgpu::QueryType::Timestamp,
                count: MAX_STAGES + 1,
            }),
            resolved: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("stage profiler"),
                size: (MAX_STAGES as u64 + 1) * 8,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            written: 0,
            period_ns: ctx.queue.get_timestamp_period(),
        });
        Self {
            ctx,
            on,
            last: Instant::now(),
            timestamps,
            labels: Vec::new(),
            times: Vec::new(),
        }
    }

    /// True when the stages are timed by GPU timestamps.
    pub fn uses_timestamps(&self) -> bool {
        self.timestamps.is_some()
    }

    /// Starts the frame (the first timestamp).
    pub fn begin(&mut self, encoder: &mut wgpu::CommandEncoder) {
        self.last = Instant::now();
        if let Some(t) = self.timestamps.as_mut() {
            encoder.write_timestamp(&t.set, 0);
            t.written = 1;
        }
    }

    /// Ends stage `label`.
    pub fn mark(&mut self, label: &'static str, encoder: &mut wgpu::CommandEncoder) {
        if !self.on {
            return;
        }
        if let Some(t) = self.timestamps.as_mut() {
            if t.written > 0 && t.written <= MAX_STAGES {
                encoder.write_timestamp(&t.set, t.written);
                t.written += 1;
                self.labels.push(label);
            }
            return;
        }
        let done = std::mem::replace(
            encoder,
            self.ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("profiled frame"),
                }),
        );
        self.ctx.queue.submit([done.finish()]);
        let _ = self.ctx.device.poll(wgpu::PollType::wait_indefinitely());
        let now = Instant::now();
        self.times.push((label, now - self.last));
        self.last = now;
    }

    /// Records the copy of the timestamps (before the frame's encoder is finished).
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        if let Some(t) = &self.timestamps
            && t.written > 1
        {
            encoder.resolve_query_set(&t.set, 0..t.written, &t.resolved, 0);
        }
    }

    /// After the frame's submit: reads the timestamps back (only while profiling) into
    /// [`StageProfiler::times`].
    pub fn read_gpu(&mut self) -> Result<(), GpuError> {
        let Some(t) = &self.timestamps else {
            return Ok(());
        };
        if t.written < 2 {
            return Ok(());
        }
        let ticks: Vec<u64> = self.ctx.read_buffer_as(&t.resolved)?;
        for (k, label) in self.labels.iter().enumerate() {
            let ns = ticks[k + 1].saturating_sub(ticks[k]) as f64 * t.period_ns as f64;
            self.times
                .push((label, Duration::from_nanos(ns.max(0.0) as u64)));
        }
        Ok(())
    }
}

impl scene_core::StageTimings for StageProfiler<'_> {
    fn stages(&self) -> Vec<(&'static str, Duration)> {
        self.times.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stage timer's two ways on the test adapter: timestamps between stages (forced on
    /// a CPU adapter, whose values only show the mechanism works: every stage labelled, in
    /// order, no time negative), and wall-clock stages, which wait for each.
    #[test]
    fn stages_are_timed_in_order_either_way() {
        let Some(ctx) = scene_core::testing::gpu_test_context() else {
            return;
        };
        let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: 1 << 20,
            usage: wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        for allow_cpu in [true, false] {
            let mut p = StageProfiler::new(&ctx, true, allow_cpu);
            if allow_cpu && !p.uses_timestamps() {
                eprintln!("no timestamps inside encoders on {}", ctx.adapter_summary());
                continue;
            }
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            p.begin(&mut encoder);
            for label in ["first", "second", "third"] {
                encoder.clear_buffer(&buffer, 0, None);
                p.mark(label, &mut encoder);
            }
            p.resolve(&mut encoder);
            ctx.queue.submit([encoder.finish()]);
            p.read_gpu().unwrap();
            let labels: Vec<&str> = p.times.iter().map(|(l, _)| *l).collect();
            assert_eq!(
                labels,
                ["first", "second", "third"],
                "timestamps: {allow_cpu}"
            );
        }
    }
}
