//! Relighting's per-pixel direct light ([`relight_pr::direct::DirectLight::PerPixel`], the
//! default of [`relight_pr::RelightTechnique`]) on a worker thread: while the view stands
//! still, every pixel's direct light from each source is gathered with rays on the CPU
//! ([`relight_pr::display::pixel_direct`]); the frame loop then hands it to the GPU display,
//! which relights it with the frame's factors like the rest. While the camera moves, the
//! display takes its direct light from the elements (the paper's display).

use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;
use std::time::Duration;

use gbuffer::CpuRasterizer;
use glam::Vec3;
use relight_pr::direct::DirectGather;
use relight_pr::display::pixel_direct;
use relight_pr::technique::Prepared;
use scene_core::{GBufferRenderer, View};

/// A request: the direct light of every pixel of `view` at `width x height`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    /// Distinguishes requests: results of older ones are dropped by the caller.
    pub generation: u64,
    /// The view.
    pub view: View,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

/// A finished request: `k` values per pixel, pixel-major.
#[derive(Debug)]
pub struct Gathered {
    /// The request answered.
    pub request: Request,
    /// The values (`k` a pixel: none at all for a scene without lights), or why the gather
    /// failed.
    pub values: Result<Vec<Vec3>, String>,
    /// Seconds the G-buffer and the gather took.
    pub seconds: f64,
}

/// The worker thread and its channels.
pub struct DirectWorker {
    requests: Option<Sender<Request>>,
    results: Receiver<Gathered>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for DirectWorker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DirectWorker").finish_non_exhaustive()
    }
}

impl DirectWorker {
    /// Starts the worker for a prepared relighting, with the gather's settings.
    pub fn new(prepared: Arc<Prepared>, subpixels: u32, emitter_rays: u32) -> Self {
        let (requests, rx) = channel::<Request>();
        let (tx, results) = channel();
        let thread = std::thread::Builder::new()
            .name("relight direct".into())
            .spawn(move || run(&prepared, subpixels, emitter_rays, &rx, &tx))
            .ok();
        Self {
            requests: Some(requests),
            results,
            thread,
        }
    }

    /// Asks for the direct light of a view (older requests still queued are skipped).
    pub fn request(&self, request: Request) {
        if let Some(r) = &self.requests {
            let _ = r.send(request);
        }
    }

    /// The newest result, if any arrived.
    pub fn latest(&self) -> Option<Gathered> {
        crate::precompute::newest(&self.results)
    }

    /// Waits up to `timeout` for the next result.
    pub fn wait(&self, timeout: Duration) -> Option<Gathered> {
        self.results.recv_timeout(timeout).ok()
    }
}

impl Drop for DirectWorker {
    fn drop(&mut self) {
        // Closing the channel ends the worker's loop.
        self.requests = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn run(
    p: &Prepared,
    subpixels: u32,
    emitter_rays: u32,
    requests: &Receiver<Request>,
    results: &Sender<Gathered>,
) {
    let mut raster = CpuRasterizer::new();
    let prepared = raster.prepare(Arc::new(p.meshing.element_scene(&p.scene)));
    let gather = DirectGather::new(&p.scene, &p.meshing, &p.solution.sources, emitter_rays);
    while let Ok(mut request) = requests.recv() {
        // Only the newest view matters.
        if let Some(newer) = crate::precompute::newest(requests) {
            request = newer;
        }
        let start = std::time::Instant::now();
        let values = match (
            &prepared,
            raster.render_view(&request.view, request.width, request.height),
        ) {
            (Ok(()), Ok(g)) => Ok(pixel_direct(&gather, &p.rays, &g, &request.view, subpixels)),
            (Err(e), _) => Err(e.to_string()),
            (_, Err(e)) => Err(e.to_string()),
        };
        let seconds = start.elapsed().as_secs_f64();
        if results
            .send(Gathered {
                request,
                values,
                seconds,
            })
            .is_err()
        {
            return;
        }
    }
}
