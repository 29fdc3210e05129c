//! The reference mode: the toolkit's path tracer ([`scene_core::reference`]) accumulating
//! one sample per pixel per pass on a worker thread while the view stands still. A new
//! view, size or light state restarts it; every pass sends the mean image back, which the
//! frame loop uploads (an upload, never a readback). Samples are those of
//! [`scene_core::reference::render_lit`] with the same seed and bounces, so the image after
//! `n` passes equals `xtask reference` at `n` samples per pixel.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};
use std::thread::JoinHandle;
use std::time::Duration;

use glam::Vec3;
use scene_core::reference::{Accumulator, Bounces, PathTracer};
use scene_core::{LightState, Scene, View};

/// What to accumulate.
#[derive(Clone, Debug, PartialEq)]
pub struct Job {
    /// Distinguishes restarts: updates of an older job are dropped.
    pub generation: u64,
    /// The view.
    pub view: View,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Light settings.
    pub lights: LightState,
    /// Bounce limit.
    pub bounces: Bounces,
    /// Seed of every random decision.
    pub seed: u64,
    /// Stop at this many samples per pixel.
    pub max_spp: u32,
}

/// A pass finished.
#[derive(Debug)]
pub struct Update {
    /// The job's generation.
    pub generation: u64,
    /// Samples per pixel so far.
    pub spp: u32,
    /// The mean image, row-major.
    pub pixels: Vec<Vec3>,
    /// Seconds the last pass took.
    pub pass_seconds: f64,
}

enum Command {
    Start(Box<Job>),
    MaxSpp(u64, u32),
    Quit,
}

/// The worker thread and its channels.
pub struct ReferenceWorker {
    commands: Sender<Command>,
    updates: Receiver<Update>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for ReferenceWorker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReferenceWorker").finish_non_exhaustive()
    }
}

impl ReferenceWorker {
    /// Starts the worker for `scene` (idle until [`ReferenceWorker::start`]).
    pub fn new(scene: Arc<Scene>) -> Self {
        let (commands, rx) = channel();
        let (tx, updates) = channel();
        let thread = std::thread::Builder::new()
            .name("reference".into())
            .spawn(move || run(&scene, &rx, &tx))
            .ok();
        Self {
            commands,
            updates,
            thread,
        }
    }

    /// Restarts accumulation with `job`.
    pub fn start(&self, job: Job) {
        let _ = self.commands.send(Command::Start(Box::new(job)));
    }

    /// Changes the sample limit of job `generation`.
    pub fn set_max_spp(&self, generation: u64, max_spp: u32) {
        let _ = self.commands.send(Command::MaxSpp(generation, max_spp));
    }

    /// The newest update, if any arrived (older ones are dropped).
    pub fn latest(&self) -> Option<Update> {
        crate::precompute::newest(&self.updates)
    }

    /// Waits up to `timeout` for the next update.
    pub fn wait(&self, timeout: Duration) -> Option<Update> {
        self.updates.recv_timeout(timeout).ok()
    }
}

impl Drop for ReferenceWorker {
    fn drop(&mut self) {
        let _ = self.commands.send(Command::Quit);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn run(scene: &Scene, commands: &Receiver<Command>, updates: &Sender<Update>) {
    let mut tracer: Option<(u64, PathTracer<'_>)> = None;
    let mut job: Option<Job> = None;
    let mut acc: Option<Accumulator> = None;
    loop {
        // Block when idle; otherwise take what arrived and go on accumulating.
        let busy = matches!((&job, &acc), (Some(j), Some(a)) if a.spp() < j.max_spp);
        let command = if busy {
            match commands.try_recv() {
                Ok(c) => Some(c),
                Err(TryRecvError::Empty) => None,
                Err(TryRecvError::Disconnected) => return,
            }
        } else {
            match commands.recv() {
                Ok(c) => Some(c),
                Err(_) => return,
            }
        };
        match command {
            Some(Command::Quit) => return,
            Some(Command::Start(j)) => {
                let fingerprint = j.lights.fingerprint();
                if tracer.as_ref().is_none_or(|(f, _)| *f != fingerprint) {
                    tracer = Some((fingerprint, PathTracer::with_lights(scene, &j.lights)));
                }
                acc = Some(Accumulator::new(j.width, j.height));
                job = Some(*j);
                continue;
            }
            Some(Command::MaxSpp(generation, n)) => {
                if let Some(j) = job.as_mut()
                    && j.generation == generation
                {
                    j.max_spp = n;
                }
                continue;
            }
            None => {}
        }
        let (Some(j), Some(a), Some((_, t))) = (&job, acc.as_mut(), &tracer) else {
            continue;
        };
        if a.spp() >= j.max_spp {
            continue;
        }
        let stats = a.add_pass(t, &j.view, j.bounces, j.seed, 1, None);
        let update = Update {
            generation: j.generation,
            spp: a.spp(),
            pixels: a.image().pixels,
            pass_seconds: stats.seconds,
        };
        if updates.send(update).is_err() {
            return;
        }
    }
}
