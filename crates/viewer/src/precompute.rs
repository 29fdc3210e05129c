//! The view-independent precomputations run on worker threads while the window stays
//! live: relighting's mesh and tagged solve, and the IBRR's construction for a light
//! state. Each reports its progress through an atomic the panel reads.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use gbuffer::CpuRasterizer;
use ibrr_ldc::{IbrrSettings, IbrrTechnique};
use relight_pr::{MeshSettings, RelightTechnique, SolverSettings};
use scene_core::{LightState, Scene};

/// The newest message waiting in `rx`, dropping the older ones (`None` when none waits):
/// what a frame loop wants from a worker that reports faster than frames come.
pub fn newest<T>(rx: &std::sync::mpsc::Receiver<T>) -> Option<T> {
    let mut last = None;
    while let Ok(m) = rx.try_recv() {
        last = Some(m);
    }
    last
}

/// A job on a worker thread producing `T`, with a progress value in [0, 1].
pub struct Background<T> {
    progress: Arc<AtomicU64>,
    handle: Option<JoinHandle<Result<T, String>>>,
    started: Instant,
    /// What it builds, for the panel.
    pub what: String,
}

impl<T: Send + 'static> std::fmt::Debug for Background<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Background")
            .field("what", &self.what)
            .field("progress", &self.progress())
            .finish()
    }
}

impl<T: Send + 'static> Background<T> {
    /// Runs `work` on a new thread; it reports progress in [0, 1] through its argument.
    pub fn spawn(
        what: &str,
        work: impl FnOnce(&dyn Fn(f64)) -> Result<T, String> + Send + 'static,
    ) -> Self {
        let progress = Arc::new(AtomicU64::new(0f64.to_bits()));
        let p = progress.clone();
        let handle = std::thread::Builder::new()
            .name(what.into())
            .spawn(move || {
                let report = |x: f64| p.store(x.clamp(0.0, 1.0).to_bits(), Ordering::Relaxed);
                work(&report)
            })
            .ok();
        Self {
            progress,
            handle,
            started: Instant::now(),
            what: what.into(),
        }
    }

    /// The progress reported so far, in [0, 1].
    pub fn progress(&self) -> f64 {
        f64::from_bits(self.progress.load(Ordering::Relaxed))
    }

    /// Time since the start.
    pub fn elapsed(&self) -> Duration {
        self.started.elapsed()
    }

    /// The result once the thread finished (`None` while it runs; a panic is an error).
    pub fn try_take(&mut self) -> Option<Result<T, String>> {
        if !self.handle.as_ref().is_some_and(|h| h.is_finished()) {
            return if self.handle.is_none() {
                Some(Err(format!("{}: could not start a thread", self.what)))
            } else {
                None
            };
        }
        let handle = self.handle.take()?;
        Some(match handle.join() {
            Ok(r) => r,
            Err(_) => Err(format!("{}: the worker thread panicked", self.what)),
        })
    }

    /// Waits for the result.
    pub fn wait(&mut self) -> Result<T, String> {
        match self.handle.take() {
            Some(h) => h
                .join()
                .unwrap_or_else(|_| Err(format!("{}: the worker thread panicked", self.what))),
            None => Err(format!("{}: no worker thread", self.what)),
        }
    }
}

/// Relighting's precomputation: mesh and solve (progressive refinement until the unshot
/// fraction reaches the solver's threshold, or hierarchically for large meshings; progress
/// is the share of the solve done).
pub fn relight(
    scene: Arc<Scene>,
    mesh: MeshSettings,
    solver: SolverSettings,
) -> Background<RelightTechnique> {
    Background::spawn("relight solve", move |report| {
        let mut t = RelightTechnique::new(mesh, solver, Box::new(CpuRasterizer::new()));
        t.prepare_with_share_done(scene, &mut |done| report(done))
            .map_err(|e| format!("relighting: {e}"))?;
        Ok(t)
    })
}

/// The IBRR's construction for `lights` (progress: IRPLs done over total).
pub fn ibrr(
    scene: Arc<Scene>,
    settings: IbrrSettings,
    lights: LightState,
) -> Background<(IbrrTechnique, LightState)> {
    Background::spawn("IBRR construction", move |report| {
        let mut t = IbrrTechnique::new(settings, Box::new(CpuRasterizer::new()));
        t.prepare_lit(scene, &lights, &mut |done, total| {
            report(done as f64 / total.max(1) as f64)
        })
        .map_err(|e| format!("IBRR: {e}"))?;
        Ok((t, lights))
    })
}
