//! The window and its frame loop (winit + wgpu surface + egui), interactive or replaying a
//! walkthrough.
//!
//! Keys: WASD to walk, Q/E down and up, Shift faster, right mouse button held to look,
//! mouse wheel for speed; 1 to 9 the scene's cameras; F1 to F8 the modes (DL, ISR, ISR
//! indirect, ISR AO, ISR coarse, relighting, IBRR, reference); F9 cycles single, split
//! and error layouts; drag the split's divider with the left button; V vsync; H the panel;
//! P or F12 a screenshot; Esc quits.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::Vec3;
use ibrr_ldc::IbrrSettings;
use relight_pr::direct::DirectLight;
use relight_pr::{MeshSettings, SolverSettings};
use scene_core::gpu::GpuContext;
use scene_core::lights::light_ids;
use scene_core::{Camera, LightId, LightState, Scene, View};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{DeviceEvent, ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use crate::args::Args;
use crate::camera::{FlyCamera, Motion};
use crate::direct::{DirectWorker, Request};
use crate::frame::{FrameSpec, Profiler, Renderer};
use crate::mode::Mode;
use crate::precompute::{self, Background};
use crate::reference::{Job, ReferenceWorker};
use crate::screenshot::{self, Shot};
use crate::script::{self, CheckedStep, LightChange, Pose, Script, Step};
use crate::ui::{self, Action, JobStatus, PanelInfo, ViewState};

/// What to tell a user whose machine has no display or no presentable adapter.
const DISPLAY_HELP: &str = "the viewer needs a display and a GPU driver that can present to \
    it. On a desktop, run it in the session; on a headless machine, start a virtual X server \
    (`apt-get install xvfb`, then `xvfb-run -s '-screen 0 1280x800x24' cargo run --release -p \
    viewer -- --scene cornell`). Without a GPU, Mesa's lavapipe renders on the CPU: \
    `apt-get install mesa-vulkan-drivers libvulkan1`";

/// Opens the scene, checks the replay file, then runs the window until it closes (or the
/// replay ends). Errors name the fault: a missing scene, a bad replay step, no display.
pub fn run(args: Args) -> Result<(), String> {
    let size = args.window_size()?;
    let scale = args.render_scale()?;
    let first_mode = Mode::parse(&args.mode)?;
    args.check_numbers()?;
    args.check_files()?;
    if let Some(path) = &args.record {
        // Fail now, not when the window closes: write an empty recording where the
        // session's will go.
        Script {
            version: crate::script::VERSION,
            steps: Vec::new(),
        }
        .write(path)?;
    }
    let opened = scene_core::open_scene_with(&args.scene, &args.added_lights()?)
        .map_err(|e| e.to_string())?;
    for note in &opened.notes {
        eprintln!("{note}");
    }
    let mut scene = opened.scene;
    if scene.cameras.is_empty() {
        // The toolkit's default view (the one `cargo xtask` commands use too): of a few
        // views around and inside the bounds, the one that sees the most lit surface.
        let camera = scene_core::rays::framing::framing_camera(&scene);
        eprintln!(
            "note: the scene has no camera; showing the default view '{}'",
            camera.name
        );
        scene.cameras.push(camera);
    }
    let steps = match &args.replay {
        Some(path) => Some(Script::read(path)?.check(&scene)?),
        None => None,
    };
    let event_loop =
        EventLoop::new().map_err(|e| format!("cannot open a window ({e}): {DISPLAY_HELP}"))?;
    let mut app = App::new(args, Arc::new(scene), steps, size, first_mode);
    app.scale = scale;
    event_loop
        .run_app(&mut app)
        .map_err(|e| format!("the event loop failed: {e}"))?;
    app.finish()
}

/// The window, its surface and egui.
struct Gfx {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    renderer: Renderer,
    egui_ctx: egui::Context,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
}

/// The reference's restart key: what it accumulates for.
#[derive(Clone, Debug, PartialEq)]
struct ReferenceKey {
    view: View,
    size: (u32, u32),
    lights: u64,
}

struct ReferenceState {
    worker: ReferenceWorker,
    generation: u64,
    key: Option<ReferenceKey>,
    running: bool,
    spp: u32,
    pass_seconds: f64,
    /// Seconds of every pass received (the replay's summary).
    passes: Vec<f64>,
    /// The CPU copy of the accumulated image (the error view's mean needs it).
    pixels: Vec<Vec3>,
    /// Error-view state: the reference spp and mode frame of the last mean.
    error: Option<(f64, u32)>,
    error_at: Option<Instant>,
}

struct App {
    args: Args,
    scene: Arc<Scene>,
    ids: Vec<LightId>,
    steps: Option<Vec<CheckedStep>>,
    step: usize,
    /// The replay step applied but not yet shown: a method it shows is still
    /// precomputing, and frames (direct light meanwhile) are drawn until it is ready.
    pending: Option<CheckedStep>,
    /// Frames drawn while a replay waited for a precomputation.
    frames_waiting: usize,
    /// The frame's size in pixels (the window's times the render scale).
    size: (u32, u32),
    /// The render scale.
    scale: f32,
    gfx: Option<Gfx>,
    state: ViewState,
    motion_keys: BTreeMap<KeyCode, bool>,
    looking: bool,
    dragging: bool,
    cursor: (f64, f64),
    last_frame: Instant,
    moved: bool,
    relight: Option<Background<relight_pr::RelightTechnique>>,
    relight_status: Option<JobStatus>,
    /// Relighting's per-pixel direct light: the worker, the last request's generation and
    /// what it asked for.
    direct: Option<DirectWorker>,
    direct_generation: u64,
    direct_requested: Option<(View, (u32, u32))>,
    /// Seconds of every per-pixel gather received (the replay's summary).
    direct_seconds: Vec<f64>,
    ibrr: Option<Background<(ibrr_ldc::IbrrTechnique, LightState)>>,
    ibrr_status: Option<JobStatus>,
    reference: ReferenceState,
    info: PanelInfo,
    mode_times: BTreeMap<String, Vec<f64>>,
    recording: Option<Script>,
    last_recorded: Option<Step>,
    screenshot: Option<String>,
    shots: u32,
    /// The scene camera jumped to this frame (recorded, so a replay gets its lens too).
    jumped: Option<usize>,
    error: Option<String>,
}

fn job_status<T: Send + 'static>(job: &Background<T>) -> JobStatus {
    JobStatus::Running(job.progress(), job.elapsed())
}

impl App {
    fn new(
        args: Args,
        scene: Arc<Scene>,
        steps: Option<Vec<CheckedStep>>,
        size: (u32, u32),
        mode: Mode,
    ) -> Self {
        let camera = FlyCamera::new(&scene.cameras[0], scene.extent());
        let state = ViewState {
            camera,
            mode,
            layout: "single",
            right: Mode::Reference,
            divider: 0.5,
            lights: LightState::default(),
            exposure: args.exposure,
            error_range: 0.5,
            vsync: !args.no_vsync && steps.is_none(),
            profile: false,
            show_ui: !args.no_ui,
        };
        let ids = light_ids(&scene);
        let recording = args.record.as_ref().map(|_| Script {
            version: script::VERSION,
            steps: Vec::new(),
        });
        Self {
            reference: ReferenceState {
                worker: ReferenceWorker::new(scene.clone()),
                generation: 0,
                key: None,
                running: false,
                spp: 0,
                pass_seconds: 0.0,
                passes: Vec::new(),
                pixels: Vec::new(),
                error: None,
                error_at: None,
            },
            args,
            scene,
            ids,
            steps,
            step: 0,
            pending: None,
            frames_waiting: 0,
            size,
            scale: 1.0,
            gfx: None,
            state,
            motion_keys: BTreeMap::new(),
            looking: false,
            dragging: false,
            cursor: (0.0, 0.0),
            last_frame: Instant::now(),
            moved: false,
            relight: None,
            relight_status: None,
            direct: None,
            direct_generation: 0,
            direct_requested: None,
            direct_seconds: Vec::new(),
            ibrr: None,
            ibrr_status: None,
            info: PanelInfo::default(),
            mode_times: BTreeMap::new(),
            recording,
            last_recorded: None,
            screenshot: None,
            shots: 0,
            jumped: None,
            error: None,
        }
    }

    /// The outcome once the loop ended: the first error, or Ok after writing the
    /// recording and printing frame times.
    fn finish(mut self) -> Result<(), String> {
        // The recording is kept even when the session ends on an error.
        if let (Some(script), Some(path)) = (&self.recording, &self.args.record) {
            let written = script.write(path);
            if let Err(w) = written {
                return Err(match self.error.take() {
                    Some(e) => format!("{e}; and the recording was lost: {w}"),
                    None => w,
                });
            }
            eprintln!(
                "recorded {} steps to {}",
                script.steps.len(),
                path.display()
            );
        }
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        if !self.mode_times.is_empty() {
            let adapter = self
                .gfx
                .as_ref()
                .map(|g| g.renderer.ctx.adapter_summary())
                .unwrap_or_default();
            println!("frame times ({}x{}, {adapter}):", self.size.0, self.size.1);
            for (mode, times) in &self.mode_times {
                println!(
                    "  {mode:<24} {:>4} frames, median {:8.2} ms",
                    times.len(),
                    median(times) * 1e3
                );
            }
            let gathers = &self.direct_seconds;
            if !gathers.is_empty() {
                println!(
                    "  relighting's per-pixel direct light (CPU) {:>4} views, median {:8.2} ms",
                    gathers.len(),
                    median(gathers) * 1e3
                );
            }
            if self.frames_waiting > 0 {
                println!(
                    "  {} frames drawn while the replay waited for a precomputation",
                    self.frames_waiting
                );
            }
            let passes = &self.reference.passes;
            if !passes.is_empty() {
                println!(
                    "  reference passes {:>4} seen, median {:8.2} ms",
                    passes.len(),
                    median(passes) * 1e3
                );
            }
        }
        Ok(())
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, e: String) {
        if self.error.is_none() {
            self.error = Some(e);
        }
        event_loop.exit();
    }

    fn create_gfx(&mut self, event_loop: &ActiveEventLoop) -> Result<Gfx, String> {
        let attributes = Window::default_attributes()
            .with_title(format!("diffuse-gi viewer: {}", self.scene.name))
            .with_inner_size(PhysicalSize::new(self.size.0, self.size.1));
        let window = Arc::new(
            event_loop
                .create_window(attributes)
                .map_err(|e| format!("cannot create a window ({e}): {DISPLAY_HELP}"))?,
        );
        let desc = wgpu::InstanceDescriptor::new_with_display_handle_from_env(Box::new(
            event_loop.owned_display_handle(),
        ));
        let backends = desc.backends;
        let instance = wgpu::Instance::new(desc);
        let surface = instance.create_surface(window.clone()).map_err(|e| {
            format!("cannot create a wgpu surface for the window ({e}): {DISPLAY_HELP}")
        })?;
        let ctx = pollster::block_on(GpuContext::with_instance(
            instance,
            backends,
            Some(&surface),
        ))
        .map_err(|e| format!("no adapter can present to the window ({e}): {DISPLAY_HELP}"))?;
        let Some(adapter) = ctx.adapter.as_ref() else {
            return Err("the GPU context has no adapter to present with".into());
        };
        let caps = surface.get_capabilities(adapter);
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| f.is_srgb())
            .or_else(|| caps.formats.first().copied())
            .ok_or_else(|| format!("the surface offers no format: {DISPLAY_HELP}"))?;
        let inner = window.inner_size();
        let (w, h) = (inner.width.max(1), inner.height.max(1));
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            format,
            width: w,
            height: h,
            present_mode: present_mode(&caps, self.state.vsync),
            desired_maximum_frame_latency: 2,
            alpha_mode: caps
                .alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Auto),
            view_formats: vec![],
            color_space: wgpu::SurfaceColorSpace::Srgb,
        };
        surface.configure(&ctx.device, &config);
        eprintln!("adapter: {}", ctx.adapter_summary());
        let mut renderer = Renderer::new(ctx.clone(), self.scene.clone(), format)?;
        let frame = renderer.fit(w, h, self.scale);
        renderer.resize(frame.0, frame.1)?;
        let on_gpu = match self.args.reference_on.as_str() {
            "gpu" => true,
            "cpu" => false,
            _ => ctx.adapter_info().device_type != wgpu::DeviceType::Cpu,
        };
        if on_gpu {
            renderer.use_gpu_reference(
                self.scene.clone(),
                scene_core::reference::PathTracerFrameSettings {
                    samples_per_frame: 4,
                    max_spp: self.args.max_spp,
                    bounces: self.args.bounces,
                    seed: self.args.seed,
                },
            )?;
        }
        eprintln!(
            "reference: {}",
            if on_gpu {
                "the GPU path tracer, 4 spp a frame"
            } else {
                "the CPU path tracer on a worker thread, 1 spp a pass"
            }
        );
        self.size = frame;
        let egui_ctx = egui::Context::default();
        let max_side = ctx.device.limits().max_texture_dimension_2d as usize;
        let egui_state = egui_winit::State::new(
            egui_ctx.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(max_side),
        );
        let egui_renderer =
            egui_wgpu::Renderer::new(&ctx.device, format, egui_wgpu::RendererOptions::default());
        Ok(Gfx {
            window,
            surface,
            config,
            renderer,
            egui_ctx,
            egui_state,
            egui_renderer,
        })
    }

    fn start_relight(&mut self) {
        if self.relight.is_none() && self.relight_status.is_none() {
            self.relight = Some(precompute::relight(
                self.scene.clone(),
                MeshSettings::elements(self.args.relight_elements),
                SolverSettings::default(),
            ));
        }
    }

    fn ibrr_settings(&self) -> IbrrSettings {
        IbrrSettings {
            resolution: self.args.ibrr_resolution,
            irpls: self.args.ibrr_irpls,
            ..Default::default()
        }
    }

    fn start_ibrr(&mut self) {
        if self.ibrr.is_none() {
            // Built with every light on as the scene describes it, from which any light
            // state is shown by relighting the layers (frame.rs).
            self.ibrr = Some(precompute::ibrr(
                self.scene.clone(),
                self.ibrr_settings(),
                LightState::default(),
            ));
        }
    }

    /// Takes finished precomputations to the GPU; with `wait`, first waits for every one
    /// the modes on screen need (a replay's frames never show a half-built method).
    fn collect_jobs(&mut self, wait: bool) -> Result<(), String> {
        let Some(gfx) = self.gfx.as_mut() else {
            return Ok(());
        };
        if let Some(job) = self.relight.as_mut() {
            let done = if wait && self.state.shows(Mode::Relight) {
                Some(job.wait())
            } else {
                job.try_take()
            };
            match done {
                Some(Ok(t)) => {
                    self.relight = None;
                    match gfx
                        .renderer
                        .set_relight(t, self.args.relight_direct == "shadow-maps")
                    {
                        Ok(p) => {
                            eprintln!(
                                "relighting ready (unshot fraction {:.2e})",
                                p.solution.stats.unshot_fraction
                            );
                            if let (
                                "pixels",
                                DirectLight::PerPixel {
                                    subpixels,
                                    emitter_rays,
                                },
                            ) = (self.args.relight_direct.as_str(), DirectLight::default())
                            {
                                self.direct = Some(DirectWorker::new(p, subpixels, emitter_rays));
                            }
                            self.relight_status = Some(JobStatus::Ready)
                        }
                        Err(e) => self.relight_status = Some(JobStatus::Failed(e)),
                    }
                }
                Some(Err(e)) => {
                    self.relight = None;
                    self.relight_status = Some(JobStatus::Failed(e));
                }
                None => self.relight_status = Some(job_status(job)),
            }
        }
        if let Some(job) = self.ibrr.as_mut() {
            let done = if wait && self.state.shows(Mode::Ibrr) {
                Some(job.wait())
            } else {
                job.try_take()
            };
            match done {
                Some(Ok((t, _lights))) => {
                    self.ibrr = None;
                    self.info.ibrr_build = t.construction().map(|c| c.describe());
                    self.ibrr_status = Some(match gfx.renderer.set_ibrr(t) {
                        Ok(()) => JobStatus::Ready,
                        Err(e) => JobStatus::Failed(e),
                    });
                }
                Some(Err(e)) => {
                    self.ibrr = None;
                    self.ibrr_status = Some(JobStatus::Failed(e));
                }
                None => self.ibrr_status = Some(job_status(job)),
            }
        }
        if wait {
            for (mode, status) in [
                (Mode::Relight, &self.relight_status),
                (Mode::Ibrr, &self.ibrr_status),
            ] {
                if let Some(JobStatus::Failed(e)) = status
                    && self.state.shows(mode)
                {
                    return Err(e.clone());
                }
            }
        }
        Ok(())
    }

    /// Moves the camera to scene camera `i` (exactly as the scene gives it).
    fn jump(&mut self, i: usize) {
        self.state.camera.camera = self.scene.cameras[i].clone();
        self.jumped = Some(i);
    }

    /// Applies a replay step (camera, mode, layout, lights, rebuilds).
    fn apply_step(&mut self, step: &CheckedStep) {
        if let Some(i) = step.scene_camera {
            self.jump(i);
        }
        if let Some((position, target)) = step.camera {
            self.state.camera.camera.position = position;
            self.state.camera.camera.target = target;
        }
        if let Some(m) = step.mode {
            self.state.mode = m;
        }
        if let Some(l) = &step.layout {
            self.state.layout = match l.as_str() {
                "split" => "split",
                "error" => "error",
                _ => "single",
            };
        }
        if let Some(r) = step.right {
            self.state.right = r;
        }
        if let Some(d) = step.divider {
            self.state.divider = d;
        }
        script::apply_lights(&mut self.state.lights, &step.lights);
        if step.rebuild_ibrr {
            self.ibrr = None;
            self.start_ibrr();
        }
        self.screenshot = step.screenshot.clone();
    }

    /// Starts the precomputations the modes on screen need.
    fn ensure_jobs(&mut self) {
        let relight_ready = self
            .gfx
            .as_ref()
            .is_some_and(|g| g.renderer.relight.is_some());
        if self.state.shows(Mode::Relight) && !relight_ready {
            self.start_relight();
        }
        let ibrr_ready = self.gfx.as_ref().is_some_and(|g| g.renderer.ibrr.is_some());
        if self.state.shows(Mode::Ibrr) && !ibrr_ready && self.ibrr_status.is_none() {
            self.start_ibrr();
        }
    }

    /// Restarts, pauses or resumes the reference for this frame's view; with `want_spp`,
    /// waits until it holds exactly that many samples per pixel.
    fn update_reference(&mut self, view: &View, want_spp: Option<u32>) -> Result<(), String> {
        let Some(gfx) = self.gfx.as_mut() else {
            return Ok(());
        };
        if gfx.renderer.has_gpu_reference() {
            return self.update_gpu_reference(view, want_spp);
        }
        let r = &mut self.reference;
        let needed = self.state.needs_reference() || want_spp.is_some();
        let key = ReferenceKey {
            view: *view,
            size: self.size,
            lights: self.state.lights.fingerprint(),
        };
        if needed && r.key.as_ref() != Some(&key) {
            // A light change at the same view and size keeps the last image on screen until
            // the restarted reference's first pass (one sample per pixel) replaces it: never
            // a black half. A new view or size clears it (the old image would not line up).
            let same_view = r
                .key
                .as_ref()
                .is_some_and(|k| k.view == key.view && k.size == key.size);
            r.generation += 1;
            r.key = Some(key);
            r.spp = 0;
            r.pixels.clear();
            r.error = None;
            r.running = true;
            if !same_view {
                let mut encoder = gfx
                    .renderer
                    .ctx
                    .device
                    .create_command_encoder(&Default::default());
                gfx.renderer.clear_reference(&mut encoder);
                gfx.renderer.ctx.queue.submit([encoder.finish()]);
            }
            r.worker.start(Job {
                generation: r.generation,
                view: *view,
                width: self.size.0,
                height: self.size.1,
                lights: self.state.lights.clone(),
                bounces: self.args.bounces,
                seed: self.args.seed,
                max_spp: want_spp.unwrap_or(self.args.max_spp),
            });
        } else if needed != r.running {
            let max = if needed { self.args.max_spp } else { 0 };
            r.worker.set_max_spp(r.generation, max.max(r.spp));
            r.running = needed;
        }
        if let Some(n) = want_spp {
            if r.spp > n {
                return Err(format!(
                    "the reference already holds {} spp, more than the {n} asked for (ask for \
                     samples before moving on, or move the camera to restart it)",
                    r.spp
                ));
            }
            r.worker.set_max_spp(r.generation, n);
            while r.spp < n {
                let Some(u) = r.worker.wait(Duration::from_secs(600)) else {
                    return Err(format!("the reference did not reach {n} spp in 10 minutes"));
                };
                r.passes.push(u.pass_seconds);
                if u.generation == r.generation {
                    r.spp = u.spp;
                    r.pass_seconds = u.pass_seconds;
                    r.pixels = u.pixels;
                }
            }
            gfx.renderer.upload_reference(&r.pixels);
        } else if let Some(u) = r.worker.latest()
            && u.generation == r.generation
        {
            r.passes.push(u.pass_seconds);
            r.spp = u.spp;
            r.pass_seconds = u.pass_seconds;
            r.pixels = u.pixels;
            gfx.renderer.upload_reference(&r.pixels);
        }
        Ok(())
    }

    /// The GPU reference's bookkeeping for this frame's view: a new view, size or light
    /// state restarts the count (the tracer restarts itself); with `want_spp` (a replay),
    /// frames are traced and waited for until the image holds exactly that many samples.
    /// The frame's own samples are traced in [`App::redraw`], inside its encoder.
    fn update_gpu_reference(&mut self, view: &View, want_spp: Option<u32>) -> Result<(), String> {
        let Some(gfx) = self.gfx.as_mut() else {
            return Ok(());
        };
        let r = &mut self.reference;
        let needed = self.state.needs_reference() || want_spp.is_some();
        r.running = needed;
        let key = ReferenceKey {
            view: *view,
            size: self.size,
            lights: self.state.lights.fingerprint(),
        };
        if needed && r.key.as_ref() != Some(&key) {
            r.key = Some(key);
            r.spp = 0;
            r.error = None;
        }
        let Some(n) = want_spp else {
            gfx.renderer.set_reference_max_spp(self.args.max_spp);
            return Ok(());
        };
        if r.spp > n {
            return Err(format!(
                "the reference already holds {} spp, more than the {n} asked for (ask for \
                 samples before moving on, or move the camera to restart it)",
                r.spp
            ));
        }
        gfx.renderer.set_reference_max_spp(n);
        let ctx = gfx.renderer.ctx.clone();
        let start = Instant::now();
        while r.spp < n {
            let t0 = Instant::now();
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            let spp = gfx
                .renderer
                .encode_reference(&mut encoder, view, &self.state.lights)?
                .unwrap_or(n);
            ctx.queue.submit([encoder.finish()]);
            ctx.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| e.to_string())?;
            r.pass_seconds = t0.elapsed().as_secs_f64();
            r.passes.push(r.pass_seconds);
            r.spp = spp;
            if start.elapsed() > Duration::from_secs(600) {
                return Err(format!("the reference did not reach {n} spp in 10 minutes"));
            }
        }
        r.pixels = gfx.renderer.read_reference()?.pixels;
        Ok(())
    }

    /// Asks for relighting's per-pixel direct light of this frame's view when relighting is
    /// on screen and it is not in hand; takes a finished gather to the GPU. With `wait`
    /// (a replay), waits for it, so the frame shows what `RelightTechnique` renders.
    fn update_direct(&mut self, view: &View, wait: bool) -> Result<(), String> {
        let (Some(worker), Some(gfx)) = (self.direct.as_ref(), self.gfx.as_mut()) else {
            return Ok(());
        };
        let Some(relight) = gfx.renderer.relight.as_ref() else {
            return Ok(());
        };
        let key = (*view, self.size);
        if !self.state.shows(Mode::Relight) || relight.has_direct(view, self.size) {
            return Ok(());
        }
        if self.direct_requested != Some(key) {
            self.direct_generation += 1;
            self.direct_requested = Some(key);
            worker.request(Request {
                generation: self.direct_generation,
                view: *view,
                width: self.size.0,
                height: self.size.1,
            });
        }
        let generation = self.direct_generation;
        let seconds = &mut self.direct_seconds;
        // Ok(true) when the newest request's values were taken, Err when its gather failed.
        let mut take = |g: crate::direct::Gathered| -> Result<bool, String> {
            seconds.push(g.seconds);
            if g.request.generation != generation {
                return Ok(false);
            }
            let values = g.values.map_err(|e| {
                format!("relighting's per-pixel direct light could not be gathered: {e}")
            })?;
            let size = (g.request.width, g.request.height);
            gfx.renderer
                .set_relight_direct(g.request.view, size, values);
            Ok(true)
        };
        if wait {
            loop {
                let g = worker
                    .wait(Duration::from_secs(600))
                    .ok_or("relighting's per-pixel direct light did not come in 10 minutes")?;
                if take(g)? {
                    break;
                }
            }
        } else if let Some(g) = worker.latest() {
            take(g)?;
        }
        Ok(())
    }

    /// The error view's scale: `error_range` times the reference's mean value.
    fn error_scale(&self) -> f32 {
        let p = &self.reference.pixels;
        if p.is_empty() {
            return 1.0;
        }
        let mean = p.iter().map(|v| (v.x + v.y + v.z) as f64).sum::<f64>() / (3 * p.len()) as f64;
        ((mean * self.state.error_range as f64) as f32).max(1e-12)
    }

    /// Records the frame's state when it differs from the last recorded one.
    fn record(&mut self, dt: f32, screenshot: Option<String>, replayed: Option<&CheckedStep>) {
        let Some(script) = self.recording.as_mut() else {
            return;
        };
        let c = &self.state.camera.camera;
        let lights: Vec<LightChange> = self
            .ids
            .iter()
            .map(|&id| {
                let s = self.state.lights.get(id);
                LightChange {
                    light: id.key(),
                    enabled: Some(s.enabled),
                    color: Some(s.color.to_array()),
                    direct: Some(s.direct),
                    indirect: Some(s.indirect),
                }
            })
            .collect();
        let mut step = Step {
            scene_camera: self.jumped.take(),
            camera: Some(Pose {
                position: c.position.to_array(),
                target: c.target.to_array(),
            }),
            mode: Some(self.state.mode.name().into()),
            layout: Some(self.state.layout.into()),
            right: Some(self.state.right.name().into()),
            divider: Some(self.state.divider),
            lights,
            ..Default::default()
        };
        // A replay recorded again keeps its waits and rebuilds, so the copy replays alike.
        if let Some(r) = replayed {
            step.reference_spp = r.reference_spp;
            step.rebuild_ibrr = r.rebuild_ibrr;
            step.no_wait = r.no_wait;
        }
        let same = self.last_recorded.as_ref() == Some(&step);
        if same && screenshot.is_none() && replayed.is_none() {
            return;
        }
        self.last_recorded = Some(step.clone());
        // Only what changed since the previous step is written.
        let previous_camera = script.steps.iter().rev().find_map(|s| s.camera);
        if previous_camera == step.camera {
            step.camera = None;
        }
        step.screenshot = screenshot;
        step.dt = Some(dt);
        script.steps.push(step);
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> Result<(), String> {
        let now = Instant::now();
        let dt = (now - self.last_frame).as_secs_f32().min(0.25);
        self.last_frame = now;
        let replaying = self.steps.is_some();
        let mut want_spp = None;
        let mut replayed = None;
        let mut wait = replaying;
        if let Some(steps) = &self.steps {
            let step = match self.pending.clone() {
                Some(step) => step,
                None => {
                    let Some(step) = steps.get(self.step).cloned() else {
                        event_loop.exit();
                        return Ok(());
                    };
                    self.step += 1;
                    self.apply_step(&step);
                    self.pending = Some(step.clone());
                    step
                }
            };
            want_spp = step.reference_spp;
            wait = !step.no_wait;
            replayed = Some(step);
        } else {
            let key = |k| *self.motion_keys.get(&k).unwrap_or(&false) as i32 as f32;
            let motion = Motion {
                forward: key(KeyCode::KeyW) - key(KeyCode::KeyS),
                right: key(KeyCode::KeyD) - key(KeyCode::KeyA),
                up: key(KeyCode::KeyE) - key(KeyCode::KeyQ),
                fast: key(KeyCode::ShiftLeft) + key(KeyCode::ShiftRight) > 0.0,
            };
            self.moved |= self.state.camera.advance(&motion, dt);
        }
        self.ensure_jobs();
        // A replay step whose methods still precompute is not shown yet: the window keeps
        // drawing (direct light in their place, the panel's progress bars) until they are
        // ready, instead of blocking on them with a black window.
        self.collect_jobs(false)?;
        let waiting = wait && self.jobs_pending();
        if wait && !waiting {
            self.collect_jobs(true)?;
        }
        if waiting {
            self.frames_waiting += 1;
        } else if replaying {
            self.pending = None;
        }
        let (w, h) = self.size;
        let camera = self.state.camera.camera_at(w, h);
        let view = View::from_camera(&camera);
        self.update_reference(&view, want_spp.filter(|_| !waiting))?;
        self.update_direct(&view, wait && !waiting)?;
        let error_scale = self.error_scale();

        let Some(gfx) = self.gfx.as_mut() else {
            return Ok(());
        };
        // Keep the surface's vsync in step with the panel.
        // The viewer's own context always has its adapter (it made it for the surface).
        let Some(adapter) = gfx.renderer.ctx.adapter.as_ref() else {
            return Ok(());
        };
        let caps = gfx.surface.get_capabilities(adapter);
        let mode = present_mode(&caps, self.state.vsync);
        if mode != gfx.config.present_mode {
            gfx.config.present_mode = mode;
            gfx.surface.configure(&gfx.renderer.ctx.device, &gfx.config);
        }

        let frame_start = Instant::now();
        let ctx = gfx.renderer.ctx.clone();
        let mut profiler = Profiler::new(&ctx, self.state.profile, false);
        let mut encoder = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("viewer frame"),
            });
        profiler.begin(&mut encoder);
        let spec = FrameSpec {
            view: &view,
            lights: &self.state.lights,
            mode: self.state.mode,
            layout: self.state.layout(),
            error_scale,
            exposure: self.state.exposure,
            surface: (gfx.config.width, gfx.config.height),
        };
        if self.reference.running && gfx.renderer.has_gpu_reference() {
            // Its samples are traced inside the frame: the frame time is the pass time
            // (the panel's timings; a pass here is a frame's 4 spp).
            if let Some(spp) =
                gfx.renderer
                    .encode_reference(&mut encoder, &view, &self.state.lights)?
            {
                self.reference.spp = spp;
                self.reference.pass_seconds = f64::from(dt);
            }
            profiler.mark("reference (GPU path tracer)", &mut encoder);
        }
        gfx.renderer
            .encode_frame(&mut encoder, &spec, &mut profiler)?;

        // The panel.
        self.info.adapter = ctx.adapter_summary();
        self.info.size = self.size;
        self.info.relight = self.relight_status.clone();
        self.info.relight_shadow_maps =
            gfx.renderer.relight.is_some() && self.args.relight_direct == "shadow-maps";
        self.info.relight_direct = match (&self.direct, gfx.renderer.relight.as_ref()) {
            (Some(_), Some(r)) => Some(r.has_direct(&view, self.size)),
            _ => None,
        };
        self.info.ibrr = self.ibrr_status.clone();
        self.info.ibrr_stale = gfx
            .renderer
            .ibrr
            .as_ref()
            .is_some_and(|b| b.is_stale(&self.state.lights))
            && self.ibrr.is_none();
        self.info.reference =
            (self.reference.spp > 0).then_some((self.reference.spp, self.reference.pass_seconds));
        self.info.mean_error = self.reference.error;
        let raw = gfx.egui_state.take_egui_input(&gfx.window);
        let mut actions = Vec::new();
        let (scene, ids, info) = (&self.scene, &self.ids, &self.info);
        let state = &mut self.state;
        let output = gfx.egui_ctx.run_pass(raw, |ctx| {
            actions = ui::panel(ctx, state, scene, ids, info);
        });
        gfx.egui_state
            .handle_platform_output(&gfx.window, output.platform_output);
        let jobs = gfx
            .egui_ctx
            .tessellate(output.shapes, output.pixels_per_point);
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [gfx.config.width, gfx.config.height],
            pixels_per_point: output.pixels_per_point,
        };
        let mut textures = output.textures_delta;
        for (id, deltas) in textures.set.drain() {
            for delta in &deltas {
                gfx.egui_renderer
                    .update_texture(&ctx.device, &ctx.queue, id, delta);
            }
        }
        let freed: Vec<egui::TextureId> = textures.free.drain().collect();
        let mut extra =
            gfx.egui_renderer
                .update_buffers(&ctx.device, &ctx.queue, &mut encoder, &jobs, &screen);

        let surface_texture = match gfx.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => Some(t),
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                gfx.surface.configure(&ctx.device, &gfx.config);
                None
            }
            _ => None,
        };
        if let Some(texture) = &surface_texture {
            let target = texture.texture.create_view(&Default::default());
            let mut pass = encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("viewer present"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &target,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                })
                .forget_lifetime();
            gfx.renderer.draw_present(&mut pass);
            gfx.egui_renderer.render(&mut pass, &jobs, &screen);
        }
        profiler.mark("present and panel", &mut encoder);
        profiler.resolve(&mut encoder);
        extra.push(encoder.finish());
        ctx.queue.submit(extra);
        if let Some(texture) = surface_texture {
            gfx.window.pre_present_notify();
            ctx.queue.present(texture);
        }
        for id in &freed {
            gfx.egui_renderer.free_texture(id);
        }
        if self.state.profile || replaying {
            // Time the frame's work, not its submission.
            let _ = ctx.device.poll(wgpu::PollType::wait_indefinitely());
        }
        profiler.read_gpu().map_err(|e| e.to_string())?;
        self.info.timestamps = profiler.uses_timestamps();
        profiler
            .times
            .push(("frame (wall clock)", frame_start.elapsed()));
        let frame_seconds = frame_start.elapsed().as_secs_f64();
        if self.state.profile {
            self.info.stages = profiler.times;
        }
        self.info
            .frames
            .push_back(if replaying { frame_seconds as f32 } else { dt });
        while self.info.frames.len() > 240 {
            self.info.frames.pop_front();
        }
        let key = match self.state.layout() {
            crate::mode::Layout::Single => self.state.mode.name().to_string(),
            crate::mode::Layout::Split { right, .. } => {
                format!("{} | {}", self.state.mode.name(), right.name())
            }
            crate::mode::Layout::Error => format!("error of {}", self.state.mode.name()),
        };
        if !waiting {
            // A frame drawn while the mode precomputes is not the mode's.
            let times = self.mode_times.entry(key.clone()).or_default();
            times.push(frame_seconds);
            self.info.per_mode.insert(key, median(times));
        }

        // The error view's mean: a readback of the mode's buffer, a few times a second.
        if self.state.layout == "error" && self.reference.spp > 0 {
            let due = replaying
                || self
                    .reference
                    .error_at
                    .is_none_or(|t| t.elapsed() > Duration::from_millis(500));
            if due && self.state.mode != Mode::Reference {
                if gfx.renderer.has_gpu_reference() {
                    self.reference.pixels = gfx.renderer.read_reference()?.pixels;
                }
                let test = gfx.renderer.read_slot(0)?;
                let reference = scene_core::Image {
                    width: w,
                    height: h,
                    pixels: self.reference.pixels.clone(),
                };
                let e = imalyzer::mean_error(&reference, &test).map_err(|e| e.to_string())?;
                self.reference.error = Some((e, self.reference.spp));
                self.reference.error_at = Some(Instant::now());
            }
        }

        for a in actions {
            match a {
                Action::RebuildIbrr => {
                    self.ibrr = None;
                    self.start_ibrr();
                }
                Action::StartRelight => self.start_relight(),
                Action::Screenshot => {
                    self.shots += 1;
                    self.screenshot = Some(format!("shot-{:03}", self.shots));
                }
                Action::SceneCamera(i) => self.jump(i),
            }
        }
        if waiting {
            // The step's screenshot and record wait for its frame.
            return Ok(());
        }
        let shot = self.screenshot.take();
        if let Some(name) = &shot {
            self.save_screenshot(name, &camera)?;
        }
        self.record(dt, shot, replayed.as_ref());
        Ok(())
    }

    /// True while a method on screen still precomputes (relighting's solve, the IBRR's
    /// construction).
    fn jobs_pending(&self) -> bool {
        (self.state.shows(Mode::Relight) && self.relight.is_some())
            || (self.state.shows(Mode::Ibrr) && self.ibrr.is_some())
    }

    fn save_screenshot(&mut self, name: &str, camera: &Camera) -> Result<(), String> {
        let Some(gfx) = self.gfx.as_ref() else {
            return Ok(());
        };
        let image = gfx.renderer.read_frame()?;
        let layout = self.state.layout();
        let split = matches!(layout, crate::mode::Layout::Split { .. });
        let shows_reference = self.state.needs_reference();
        let path = screenshot::save(
            &self.args.screenshots,
            &image,
            &Shot {
                name,
                camera,
                lights: &self.state.lights,
                mode: self.state.mode.name(),
                layout: layout.name(),
                right: split.then(|| self.state.right.name()),
                divider: split.then_some(self.state.divider),
                reference_spp: shows_reference.then_some(self.reference.spp),
                mean_error: (self.state.layout == "error")
                    .then_some(self.reference.error.map(|e| e.0))
                    .flatten(),
                exposure: self.state.exposure,
            },
        )?;
        eprintln!("screenshot: {}", path.display());
        if let (true, Some((e, spp))) = (self.state.layout == "error", self.reference.error) {
            println!(
                "mean error (eq. 19) of {} against the reference at {spp} spp: {e:.6}",
                self.state.mode.name()
            );
        }
        Ok(())
    }

    fn key(&mut self, code: KeyCode, pressed: bool, event_loop: &ActiveEventLoop) {
        if matches!(
            code,
            KeyCode::KeyW
                | KeyCode::KeyA
                | KeyCode::KeyS
                | KeyCode::KeyD
                | KeyCode::KeyQ
                | KeyCode::KeyE
                | KeyCode::ShiftLeft
                | KeyCode::ShiftRight
        ) {
            self.motion_keys.insert(code, pressed);
            return;
        }
        if !pressed {
            return;
        }
        let modes = [
            KeyCode::F1,
            KeyCode::F2,
            KeyCode::F3,
            KeyCode::F4,
            KeyCode::F5,
            KeyCode::F6,
            KeyCode::F7,
            KeyCode::F8,
        ];
        if let Some(i) = modes.iter().position(|&k| k == code) {
            self.state.mode = Mode::ALL[i];
            return;
        }
        let digits = [
            KeyCode::Digit1,
            KeyCode::Digit2,
            KeyCode::Digit3,
            KeyCode::Digit4,
            KeyCode::Digit5,
            KeyCode::Digit6,
            KeyCode::Digit7,
            KeyCode::Digit8,
            KeyCode::Digit9,
        ];
        if let Some(i) = digits.iter().position(|&k| k == code) {
            if i < self.scene.cameras.len() {
                self.jump(i);
            }
            return;
        }
        match code {
            KeyCode::F9 => {
                self.state.layout = match self.state.layout {
                    "single" => "split",
                    "split" => "error",
                    _ => "single",
                }
            }
            KeyCode::KeyV => self.state.vsync = !self.state.vsync,
            KeyCode::KeyH => self.state.show_ui = !self.state.show_ui,
            KeyCode::KeyP | KeyCode::F12 => {
                self.shots += 1;
                self.screenshot = Some(format!("shot-{:03}", self.shots));
            }
            KeyCode::Escape => event_loop.exit(),
            _ => {}
        }
    }
}

fn present_mode(caps: &wgpu::SurfaceCapabilities, vsync: bool) -> wgpu::PresentMode {
    let wanted: &[wgpu::PresentMode] = if vsync {
        &[wgpu::PresentMode::Fifo]
    } else {
        &[wgpu::PresentMode::Immediate, wgpu::PresentMode::Mailbox]
    };
    wanted
        .iter()
        .copied()
        .find(|m| caps.present_modes.contains(m))
        .unwrap_or(wgpu::PresentMode::Fifo)
}

fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[s.len() / 2]
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_some() {
            return;
        }
        match self.create_gfx(event_loop) {
            Ok(g) => {
                g.window.request_redraw();
                self.gfx = Some(g);
                if !self.args.lazy && self.steps.is_none() {
                    self.start_relight();
                }
            }
            Err(e) => self.fail(event_loop, e),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(gfx) = self.gfx.as_mut() else {
            return;
        };
        let consumed = gfx.egui_state.on_window_event(&gfx.window, &event).consumed;
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) if size.width > 0 && size.height > 0 => {
                gfx.config.width = size.width;
                gfx.config.height = size.height;
                gfx.surface.configure(&gfx.renderer.ctx.device, &gfx.config);
                let frame = gfx.renderer.fit(size.width, size.height, self.scale);
                if let Err(e) = gfx.renderer.resize(frame.0, frame.1) {
                    self.fail(event_loop, e);
                    return;
                }
                self.size = frame;
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.redraw(event_loop) {
                    self.fail(event_loop, e);
                }
            }
            WindowEvent::KeyboardInput { event, .. } if !consumed => {
                if let PhysicalKey::Code(code) = event.physical_key
                    && self.steps.is_none()
                {
                    self.key(code, event.state == ElementState::Pressed, event_loop);
                }
            }
            WindowEvent::MouseInput { state, button, .. } => {
                let pressed = state == ElementState::Pressed;
                match button {
                    MouseButton::Right => self.looking = pressed && !consumed,
                    MouseButton::Left => {
                        let window = gfx.config.width as f64;
                        let near_divider = self.state.layout == "split"
                            && (self.cursor.0 - self.state.divider as f64 * window).abs() < 8.0;
                        self.dragging = pressed && !consumed && near_divider;
                    }
                    _ => {}
                }
            }
            WindowEvent::CursorMoved { position, .. } => {
                self.cursor = (position.x, position.y);
                if self.dragging && gfx.config.width > 0 {
                    self.state.divider =
                        (position.x / gfx.config.width as f64).clamp(0.0, 1.0) as f32;
                }
            }
            WindowEvent::MouseWheel { delta, .. } if !consumed => {
                let y = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                let s = &mut self.state.camera.speed_scale;
                *s = (*s * 1.2f32.powf(y)).clamp(0.01, 100.0);
            }
            _ => {}
        }
    }

    fn device_event(
        &mut self,
        _event_loop: &ActiveEventLoop,
        _device: winit::event::DeviceId,
        event: DeviceEvent,
    ) {
        if let DeviceEvent::MouseMotion { delta } = event
            && self.looking
            && self.steps.is_none()
        {
            self.moved |= self
                .state
                .camera
                .look(delta.0 as f32, delta.1 as f32, 0.003);
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(g) = &self.gfx {
            g.window.request_redraw();
        }
    }
}
