//! Each method's GPU frame hosted as a [`Technique`], so that the main job with `--gpu` times
//! what an engine pays for the method, not the harness around it ([`FrameTechnique`]); the
//! method makers it and `bench frames` share; the GPU path tracer as the main job's
//! reference renderer ([`GpuReference`]); and the GPU time between two points of an encoder
//! ([`GpuSpan`]).
//!
//! A frame of a [`FrameTechnique`]: the G-buffer is rasterised on the GPU (gbuffer's
//! [`GpuRasterizer`]) and waited for; then, timed, the method's [`GpuFrame::encode`] is
//! recorded, submitted and waited for; then, untimed, the target is read back for scoring.
//! The time is the GPU's own between the frame's first and last commands where the adapter
//! has timestamp queries and is not a CPU, else the wall clock from recording to completion
//! ([`DeviceClock`]). Readbacks and GPU objects created inside each timed frame are counted
//! ([`FrameTechnique::timed_readbacks`]): the frame contract reads nothing back.
//!
//! A GPU left idle lowers its clocks, and an engine does not leave it idle. On an NVIDIA
//! H200 (2026-11-28, `nvidia-smi` sampling every 100-200 ms) the shader clock sat at 345 MHz
//! idle and fell back to it 3 to 3.5 s after work stopped. It rose to its working 1 980 MHz
//! within 0.2 to 0.4 s of work at 98 % utilisation, but frames submitted one at a time and
//! waited for (40 to 50 %) took 2.4 s, and in one run over 3.5 s; a short burst (a small
//! reference render) did not raise it at all. `bench frames` timed at the idle clock read 2
//! to 5 times its figures at the working clock. So where frames are timed by GPU
//! timestamps, a timed frame on a device that has had no timed frame for [`COOLS_AFTER`] is
//! preceded by [`WARM_UP`] of the same method's frames, untimed, many to a submission so that
//! the device is saturated ([`Warmth`]). On a CPU adapter nothing is done: there is no clock
//! to raise.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use bench_harness::{HarnessError, ReferenceRenderer, RenderedReference};
use gbuffer::{GpuPreparedScene, GpuRasterizer};
use scene_core::gpu::{FrameInputs, GpuContext, GpuFrame, GpuGBuffer, ObjectCounts};
use scene_core::reference::ReferenceSettings;
use scene_core::shadowed_lights::{LightSet, ShadowSettings};
use scene_core::{
    DeviceClock, DeviceTime, Error, FrameRequest, Image, LightState, Scene, Technique, View,
};

/// GPU time between two points of a command encoder: an empty compute pass writing a
/// timestamp at its beginning, and another writing one at its end (`TIMESTAMP_QUERY`
/// only). `None` on a CPU adapter, whose timestamps do not time the work (`PassTimer`).
pub struct GpuSpan {
    set: wgpu::QuerySet,
    resolved: wgpu::Buffer,
    period_ns: f64,
}

impl GpuSpan {
    /// A span on `ctx`'s device, or `None` without timestamp queries or on a CPU adapter.
    pub fn new(ctx: &GpuContext) -> Option<Self> {
        if !ctx
            .device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
            || ctx.adapter_info().device_type == wgpu::DeviceType::Cpu
        {
            return None;
        }
        Some(Self {
            set: ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("frame span"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            }),
            resolved: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("frame span"),
                size: 16,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            period_ns: f64::from(ctx.queue.get_timestamp_period()),
        })
    }

    /// Records the mark at the beginning (`end` false) or the end of the span.
    pub fn mark(&self, encoder: &mut wgpu::CommandEncoder, end: bool) {
        let index = Some(u32::from(end));
        encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("frame span"),
            timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                query_set: &self.set,
                beginning_of_pass_write_index: if end { None } else { index },
                end_of_pass_write_index: if end { index } else { None },
            }),
        });
        if end {
            encoder.resolve_query_set(&self.set, 0..2, &self.resolved, 0);
        }
    }

    /// Milliseconds between the marks (after the submission has run; a readback).
    pub fn read(&self, ctx: &GpuContext) -> Result<f64, String> {
        let t: Vec<u64> = ctx
            .read_buffer_as(&self.resolved)
            .map_err(|e| e.to_string())?;
        Ok(t[1].saturating_sub(t[0]) as f64 * self.period_ns * 1e-6)
    }
}

/// Idle time after which the device's clocks may have dropped (the H200 kept them 3 s).
pub const COOLS_AFTER: Duration = Duration::from_secs(1);

/// How long the device is kept saturated before a timed frame on a device that may have
/// cooled. The H200's clock rose from idle to its working value within 0.2 to 0.4 s of work
/// at 98 % utilisation, but took 2.4 to over 3.5 s of frames submitted one by one (40 to
/// 50 %), so the warm-up records many frames per submission.
pub const WARM_UP: Duration = Duration::from_secs(1);

/// A warm-up submission grows (doubling its frames, up to [`MAX_WARM_BATCH`]) while it takes
/// less than this: the submission and the wait are then a small share of the device's time.
const WARM_BATCH_TIME: Duration = Duration::from_millis(20);

/// The most frames recorded into one warm-up submission.
const MAX_WARM_BATCH: u32 = 256;

/// When this process last had timed frames, or a warm-up, on the device (module docs): a
/// short burst of other work does not raise the clocks, so only these count.
static LAST_BUSY: Mutex<Option<Instant>> = Mutex::new(None);

/// The device-clock warm-up of timed frames (module docs).
pub struct Warmth;

impl Warmth {
    /// Notes that a timed frame, or a warm-up, has just finished on the device.
    pub fn busy() {
        if let Ok(mut last) = LAST_BUSY.lock() {
            *last = Some(Instant::now());
        }
    }

    /// Whether the device has had no timed frame or warm-up for longer than [`COOLS_AFTER`]
    /// (or never).
    pub fn cooled() -> bool {
        Self::cooled_since(LAST_BUSY.lock().ok().and_then(|l| *l), Instant::now())
    }

    /// [`Warmth::cooled`] for a last busy instant and a present one.
    pub fn cooled_since(last: Option<Instant>, now: Instant) -> bool {
        last.is_none_or(|t| now.saturating_duration_since(t) > COOLS_AFTER)
    }

    /// When `needed` (frames timed on the device, which has [`cooled`](Warmth::cooled)),
    /// keeps the device saturated for [`WARM_UP`]: submissions of frames recorded by
    /// `record`, each submission handed to `submit_and_wait`, their frame count doubling
    /// while a submission takes under 20 ms. Returns the frames run (0 when not needed).
    pub fn before_timing<E>(
        needed: bool,
        device: &wgpu::Device,
        mut record: impl FnMut(&mut wgpu::CommandEncoder) -> Result<(), E>,
        mut submit_and_wait: impl FnMut(wgpu::CommandEncoder) -> Result<(), E>,
    ) -> Result<u32, E> {
        if !needed {
            return Ok(0);
        }
        let start = Instant::now();
        let (mut frames, mut batch) = (0, 1);
        while start.elapsed() < WARM_UP {
            let t0 = Instant::now();
            let mut encoder = device.create_command_encoder(&Default::default());
            for _ in 0..batch {
                record(&mut encoder)?;
            }
            submit_and_wait(encoder)?;
            frames += batch;
            if t0.elapsed() < WARM_BATCH_TIME {
                batch = (batch * 2).min(MAX_WARM_BATCH);
            }
        }
        Self::busy();
        Ok(frames)
    }
}

/// A method on the frame contract, boxed for hosting.
pub type BoxedFrame = Box<dyn GpuFrame + Send>;

/// Prepares a method's frame for a scene on a device: its whole precomputation.
pub type FrameMaker = Box<dyn FnMut(&GpuContext, &Arc<Scene>) -> Result<BoxedFrame, Error> + Send>;

/// The scene's shadowed lights at the default shadow settings.
fn shadowed_lights(scene: &Scene) -> Result<LightSet, Error> {
    LightSet::new(scene, &ShadowSettings::default()).map_err(|e| Error::method("shadow maps", e))
}

/// ISR (or DL, with [`isr::IsrSettings::dl`]) with `settings`, over the scene's shadowed
/// lights at the default shadow settings.
pub fn isr_maker(settings: isr::IsrSettings) -> FrameMaker {
    Box::new(move |ctx, scene| {
        let lights = shadowed_lights(scene)?;
        let mut frame =
            isr::IsrFrame::prepare(ctx, &lights, settings).map_err(|e| Error::method("isr", e))?;
        if settings.light_senders > 0 {
            let senders = isr::LightSenders::with_bounces(
                scene,
                &lights,
                settings.light_senders,
                settings.light_sender_bounces,
            )
            .map_err(|e| Error::method("isr", e))?;
            frame = frame
                .with_light_senders(&senders)
                .map_err(|e| Error::method("isr", e))?;
        }
        Ok(Box::new(frame) as BoxedFrame)
    })
}

/// Relighting at an element target of `elements`, its form factors at `precision` on the
/// GPU, with the per-pixel direct light of the GPU shadow maps (3 x 3 footprint samples, the
/// relighting technique's GPU default).
pub fn relight_maker(elements: usize, precision: relight_pr::packed::Precision) -> FrameMaker {
    Box::new(move |ctx, scene| {
        let prepared = relight_pr::Prepared::solve(
            scene.clone(),
            &relight_pr::MeshSettings::elements(elements),
            &relight_pr::SolverSettings::default(),
            &mut |_| {},
        )
        .map_err(|e| Error::method("relight-pr", e))?;
        let lights = shadowed_lights(scene)?;
        let settings = relight_pr::RelightFrameSettings {
            precision,
            shadowed_direct: Some((&lights, 3)),
        };
        let frame = relight_pr::RelightFrame::prepare(ctx, &prepared, &settings)
            .map_err(|e| Error::method("relight-pr", e))?;
        Ok(Box::new(frame) as BoxedFrame)
    })
}

/// The IBRR with `settings`, its layered depth cube built on the CPU (hemicubes rasterised
/// there, as the main job's CPU IBRR does) and put on the GPU.
pub fn ibrr_maker(settings: ibrr_ldc::IbrrSettings) -> FrameMaker {
    Box::new(move |ctx, scene| {
        let mut ibrr =
            ibrr_ldc::IbrrTechnique::new(settings, Box::new(gbuffer::CpuRasterizer::new()));
        ibrr.prepare(scene.clone())?;
        let frame =
            ibrr_ldc::IbrrFrame::prepare(ctx, ibrr).map_err(|e| Error::method("ibrr-ldc", e))?;
        Ok(Box::new(frame) as BoxedFrame)
    })
}

/// What a [`FrameTechnique`] keeps per frame size: the G-buffer and the target.
struct Targets {
    gbuffer: GpuGBuffer,
    target: wgpu::Texture,
}

/// A method's GPU frame as a [`Technique`] (module docs): [`Technique::render`] draws the
/// G-buffer on the GPU, times the method's frame alone, and reads the image back after;
/// [`Technique::device_time`] gives the timed part.
pub struct FrameTechnique {
    name: String,
    ctx: GpuContext,
    make: FrameMaker,
    raster: GpuRasterizer,
    span: Option<GpuSpan>,
    prepared: Option<(GpuPreparedScene, BoxedFrame)>,
    targets: Option<Targets>,
    last: Option<DeviceTime>,
    timed_readbacks: u64,
    timed_frames: u64,
    last_created: ObjectCounts,
}

impl std::fmt::Debug for FrameTechnique {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrameTechnique")
            .field("name", &self.name)
            .field("timed_frames", &self.timed_frames)
            .finish_non_exhaustive()
    }
}

fn gpu_error(e: impl std::fmt::Display) -> Error {
    Error::from(scene_core::gpu::GpuError::Validation(e.to_string()))
}

impl FrameTechnique {
    /// The method `make` prepares, named `name` in reports, on `ctx`'s device.
    pub fn new(name: &str, ctx: &GpuContext, make: FrameMaker) -> Result<Self, String> {
        Ok(Self {
            name: name.into(),
            raster: GpuRasterizer::new(ctx).map_err(|e| e.to_string())?,
            span: GpuSpan::new(ctx),
            ctx: ctx.clone(),
            make,
            prepared: None,
            targets: None,
            last: None,
            timed_readbacks: 0,
            timed_frames: 0,
            last_created: ObjectCounts::default(),
        })
    }

    /// Readbacks made inside the timed part of every frame so far (zero for a method on the
    /// frame contract).
    #[cfg(test)]
    pub fn timed_readbacks(&self) -> u64 {
        self.timed_readbacks
    }

    /// Frames timed so far.
    #[cfg(test)]
    pub fn timed_frames(&self) -> u64 {
        self.timed_frames
    }

    /// The GPU objects the last frame's recording created.
    #[cfg(test)]
    pub fn last_created(&self) -> ObjectCounts {
        self.last_created
    }

    /// The G-buffer and target of `w x h`, kept while the size stays.
    fn targets(&mut self, w: u32, h: u32) -> Result<(), Error> {
        if self
            .targets
            .as_ref()
            .is_none_or(|t| (t.gbuffer.width, t.gbuffer.height) != (w, h))
        {
            self.targets = None;
            let gbuffer = GpuGBuffer::new(&self.ctx, w, h)?;
            let target = self.ctx.validated(|| {
                self.ctx.create_texture_2d(
                    "frame technique target",
                    w,
                    h,
                    wgpu::TextureFormat::Rgba32Float,
                    wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
                )
            })?;
            self.targets = Some(Targets { gbuffer, target });
        }
        Ok(())
    }
}

/// Submits `encoder` on `ctx`'s queue and waits until the device has run it.
fn submit_and_wait(ctx: &GpuContext, encoder: wgpu::CommandEncoder) -> Result<(), Error> {
    ctx.validated(|| ctx.queue.submit([encoder.finish()]))?;
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map(|_| ())
        .map_err(gpu_error)
}

impl Technique for FrameTechnique {
    fn name(&self) -> &str {
        &self.name
    }

    fn prepare(&mut self, scene: Arc<Scene>) -> Result<(), Error> {
        self.prepared = None;
        scene_core::contract::check(&scene)?;
        let uploaded = self.raster.upload(&scene)?;
        let frame = (self.make)(&self.ctx, &scene)?;
        self.prepared = Some((uploaded, frame));
        Ok(())
    }

    fn render(&mut self, frame: &FrameRequest<'_>) -> Result<Image, Error> {
        if self.prepared.is_none() {
            return Err(Error::NotPrepared(format!("technique '{}'", self.name)));
        }
        self.last = None;
        let (w, h) = (frame.width, frame.height);
        self.targets(w, h)?;
        let (Some((uploaded, method)), Some(t)) = (self.prepared.as_mut(), self.targets.as_ref())
        else {
            unreachable!("prepared and targets checked above");
        };
        // Whether the device has cooled, asked before the G-buffer's work.
        let cooled = Warmth::cooled();
        // The G-buffer, untimed: the engine has its own.
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        self.raster
            .encode(&mut encoder, uploaded, &frame.view, &t.gbuffer)?;
        submit_and_wait(&self.ctx, encoder)?;
        let inputs = FrameInputs {
            gbuffer: &t.gbuffer,
            view: &frame.view,
            lights: frame.lights,
        };
        // The device's working clocks, as an engine that keeps it busy finds them.
        Warmth::before_timing(
            self.span.is_some() && cooled,
            &self.ctx.device,
            |encoder| method.encode(encoder, &inputs, &t.target),
            |encoder| submit_and_wait(&self.ctx, encoder),
        )?;
        // The method's frame, timed.
        let readbacks = self.ctx.readbacks();
        let t0 = Instant::now();
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        if let Some(span) = &self.span {
            span.mark(&mut encoder, false);
        }
        let (recorded, created) = ObjectCounts::during(&self.ctx.device, || {
            method.encode(&mut encoder, &inputs, &t.target)
        });
        recorded?;
        if let Some(span) = &self.span {
            span.mark(&mut encoder, true);
        }
        submit_and_wait(&self.ctx, encoder)?;
        let wall = t0.elapsed().as_secs_f64();
        Warmth::busy();
        let read = self.ctx.readbacks() - readbacks;
        self.timed_readbacks += read;
        self.timed_frames += 1;
        self.last_created = created;
        if read > 0 {
            // A time with a readback inside is not the method's frame on the contract.
            return Err(Error::from(scene_core::gpu::GpuError::Readback(format!(
                "method '{}' read back {read} time(s) inside its timed frame (the frame \
                 contract reads nothing back); its time is not reported",
                self.name
            ))));
        }
        // Untimed: the span's timestamps and the image, for scoring.
        let last = match &self.span {
            Some(span) => DeviceTime {
                seconds: span.read(&self.ctx).map_err(gpu_error)? * 1e-3,
                clock: DeviceClock::Timestamps,
            },
            None => DeviceTime {
                seconds: wall,
                clock: DeviceClock::WallAfterWait,
            },
        };
        let image = self.ctx.read_texture_image(&t.target)?;
        self.last = Some(last);
        Ok(image)
    }

    fn device_time(&self) -> Option<DeviceTime> {
        self.last
    }
}

/// The GPU path tracer ([`scene_core::reference::render_gpu`]) as the main job's reference
/// renderer: references and the equal-error ladder on the device the methods run on, the
/// ladder's seconds those of its passes (the scene's upload and the pipeline left out, as a
/// method's precomputation is).
#[derive(Clone, Debug)]
pub struct GpuReference {
    ctx: GpuContext,
}

impl GpuReference {
    /// The tracer on `ctx`'s device.
    pub fn new(ctx: &GpuContext) -> Self {
        Self { ctx: ctx.clone() }
    }
}

impl ReferenceRenderer for GpuReference {
    fn describe(&self) -> String {
        format!("the GPU path tracer on {}", self.ctx.adapter_summary())
    }

    fn key_tag(&self) -> &str {
        "gpu path tracer"
    }

    fn render(
        &self,
        scene: &Scene,
        view: &View,
        settings: &ReferenceSettings,
        lights: &LightState,
        progress: Option<&(dyn Fn(u64, u64) + Sync)>,
    ) -> Result<RenderedReference, HarnessError> {
        let rows = u64::from(settings.height);
        let by_rows = progress.map(|p| {
            move |done: u32, total: u32| p(u64::from(done) * rows / u64::from(total.max(1)), rows)
        });
        let out = scene_core::reference::render_gpu(
            &self.ctx,
            scene,
            view,
            settings,
            lights,
            by_rows.as_ref().map(|f| f as &dyn Fn(u32, u32)),
        )
        .map_err(|e| HarnessError::from(Error::from(e)))?;
        Ok(RenderedReference {
            image: out.image,
            seconds: out.seconds,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene_core::builtin;
    use scene_core::testing::gpu_test_context;

    /// Two views of the Cornell box's camera, a little apart.
    fn views(scene: &Scene) -> [scene_core::Camera; 2] {
        let c = scene.cameras[0].clone();
        let mut moved = c.clone();
        moved.position += glam::Vec3::new(0.05, 0.02, 0.0);
        [c, moved]
    }

    /// The warm-up's rule: a device never busy, or idle for longer than [`COOLS_AFTER`], has
    /// cooled; one busy a moment ago has not; no warm-up runs unless needed, and a frame that
    /// fails ends it with its error.
    #[test]
    fn a_device_idle_for_a_second_is_warmed_before_timing() {
        let now = Instant::now();
        assert!(Warmth::cooled_since(None, now));
        assert!(!Warmth::cooled_since(Some(now), now));
        let earlier = now.checked_sub(COOLS_AFTER + Duration::from_millis(10));
        assert!(earlier.is_none() || Warmth::cooled_since(earlier, now));
        let recent = now.checked_sub(COOLS_AFTER / 2);
        assert!(recent.is_none() || !Warmth::cooled_since(recent, now));
        let Some(ctx) = gpu_test_context() else {
            return;
        };
        let device = &ctx.device;
        let never = |_: wgpu::CommandEncoder| -> Result<(), &str> { Err("submitted") };
        assert_eq!(
            Warmth::before_timing(false, device, |_| Err("recorded"), never),
            Ok(0)
        );
        assert_eq!(
            Warmth::before_timing(true, device, |_| Err("lost"), never),
            Err("lost")
        );
        // A warm-up that runs: frames recorded into growing submissions for WARM_UP.
        let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("warm-up test"),
            size: 1 << 16,
            usage: wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let (mut recorded, mut submissions) = (0_u32, 0_u32);
        let t0 = Instant::now();
        let frames = Warmth::before_timing(
            true,
            device,
            |encoder| {
                encoder.clear_buffer(&buffer, 0, None);
                recorded += 1;
                Ok::<(), String>(())
            },
            |encoder| {
                submissions += 1;
                submit_and_wait(&ctx, encoder).map_err(|e| e.to_string())
            },
        )
        .unwrap();
        assert!(t0.elapsed() >= WARM_UP);
        assert_eq!(frames, recorded);
        assert!(
            submissions < frames,
            "{frames} frames in {submissions} submissions: the batches did not grow"
        );
        assert!(!Warmth::cooled(), "a warm-up leaves the device warm");
    }

    /// Every method's frame, hosted as the main job hosts it with `--gpu`: a time measured
    /// on the device, nothing read back inside it, no GPU object created by a frame once
    /// the size has been seen, and an image (finite, lit) of the asked size.
    #[test]
    fn every_method_frame_is_timed_without_a_readback() {
        let Some(ctx) = gpu_test_context() else {
            return;
        };
        let scene = Arc::new(builtin::scene("cornell").unwrap());
        let makers: Vec<(&str, FrameMaker)> = vec![
            ("dl", isr_maker(isr::IsrSettings::dl())),
            ("isr", isr_maker(isr::IsrSettings::default())),
            (
                "relight",
                relight_maker(64, relight_pr::packed::Precision::F32),
            ),
            (
                "ibrr",
                ibrr_maker(ibrr_ldc::IbrrSettings {
                    target_error: 0.0,
                    resolution: 64,
                    irpls: 8,
                    ..Default::default()
                }),
            ),
        ];
        let [a, b] = views(&scene);
        let (w, h) = (24, 18);
        for (name, make) in makers {
            let mut t = FrameTechnique::new(name, &ctx, make).unwrap();
            t.prepare(scene.clone()).unwrap();
            let readbacks = ctx.readbacks();
            for cam in [&a, &b, &a, &b] {
                let image = t.render(&FrameRequest::camera(cam, w, h)).unwrap();
                let time = t.device_time().expect("a device time after a frame");
                assert!(
                    time.seconds > 0.0 && time.seconds.is_finite(),
                    "{name}: {time:?}"
                );
                assert_eq!((image.width, image.height), (w, h), "{name}");
                assert_eq!(image.non_finite_count(), 0, "{name}");
                assert!(image.mean().max_element() > 0.0, "{name}: a black frame");
            }
            assert_eq!(t.timed_frames(), 4, "{name}");
            assert_eq!(
                t.timed_readbacks(),
                0,
                "{name}: read back inside a timed frame"
            );
            // The readbacks outside the timed frames (the image, and the span where there
            // is one) were counted: the counter counts.
            assert!(
                ctx.readbacks() >= readbacks + 4,
                "{name}: readbacks not counted"
            );
            if ObjectCounts::available(&ctx.device) {
                assert!(
                    t.last_created().is_zero(),
                    "{name}: a frame at a seen size created {}",
                    t.last_created()
                );
            }
        }
    }

    /// A frame that breaks the contract by reading a buffer back while it records.
    struct ReadsBack(GpuContext, wgpu::Buffer);

    impl GpuFrame for ReadsBack {
        fn name(&self) -> &str {
            "reads-back"
        }
        fn encode(
            &mut self,
            _: &mut wgpu::CommandEncoder,
            _: &FrameInputs<'_>,
            _: &wgpu::Texture,
        ) -> Result<(), Error> {
            self.0.read_buffer(&self.1)?;
            Ok(())
        }
    }

    /// The counting wrapper can fail: a frame that reads back inside its timed part is
    /// refused with an error naming the method, and no time is reported for it.
    #[test]
    fn a_frame_that_reads_back_is_refused() {
        let Some(ctx) = gpu_test_context() else {
            return;
        };
        let scene = Arc::new(builtin::scene("cornell").unwrap());
        let make: FrameMaker = Box::new(|ctx, _| {
            let buffer = ctx.buffer_with("probe", &[0u8; 16], wgpu::BufferUsages::COPY_SRC);
            Ok(Box::new(ReadsBack(ctx.clone(), buffer)) as BoxedFrame)
        });
        let mut t = FrameTechnique::new("reads-back", &ctx, make).unwrap();
        t.prepare(scene.clone()).unwrap();
        let e = t
            .render(&FrameRequest::camera(&scene.cameras[0], 8, 6))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("reads-back") && e.contains("read back 1 time"),
            "{e}"
        );
        assert!(t.device_time().is_none());
    }
}
