//! The traits the bench harness composes: a [`Technique`] renders images, a [`Metric`]
//! compares them.
//!
//! A technique is prepared once for a scene ([`Technique::prepare`], which may do all its
//! precomputation or leave some to [`Technique::refine`]), then renders any number of
//! frames ([`Technique::render`]), each from a [`View`] with that frame's [`LightState`].
//! A technique never serves a frame from data prepared for another scene: it holds the
//! scene it was prepared for (an [`Arc`]), and everything a frame may change (the view,
//! the light settings) comes with the frame. Moving a light or editing geometry makes a
//! new scene, which is prepared again.

use std::sync::Arc;
use std::time::Duration;

use crate::Error;
use crate::image::Image;
use crate::lights::LightState;
use crate::scene::{Camera, Scene};
use crate::view::View;

/// One frame to render: where from, at what size, with which light settings.
#[derive(Clone, Copy, Debug)]
pub struct FrameRequest<'a> {
    /// The view (its aspect ratio should be `width / height`).
    pub view: View,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The frame's per-light settings ([`LightState::default`]: the scene as it is).
    pub lights: &'a LightState,
}

/// The default light state, for frames that light the scene as it is.
static SCENE_LIGHTS: LightState = LightState::new();

impl FrameRequest<'static> {
    /// The frame seen by `camera` at `width x height` with the scene's own lights (the
    /// default [`LightState`]).
    pub fn camera(camera: &Camera, width: u32, height: u32) -> Self {
        Self::from_camera(camera, width, height, &SCENE_LIGHTS)
    }
}

impl<'a> FrameRequest<'a> {
    /// The frame seen by `camera`, its aspect ratio replaced by `width / height`.
    pub fn from_camera(camera: &Camera, width: u32, height: u32, lights: &'a LightState) -> Self {
        let aspect = if height > 0 {
            width as f32 / height as f32
        } else {
            camera.aspect
        };
        Self {
            view: View::from_camera(&camera.with_aspect(aspect)),
            width,
            height,
            lights,
        }
    }
}

/// What one [`Technique::refine`] step left.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refinement {
    /// True when nothing is left to refine.
    pub done: bool,
    /// Steps taken so far (shots, light paths...), for reports.
    pub steps: u64,
    /// The method's own estimate of what is left, in its own unit (for progressive
    /// radiosity, the unshot fraction of the emitted energy), when it has one.
    pub remaining: Option<f64>,
}

impl Refinement {
    /// Nothing to refine (what techniques that precompute everything in `prepare` report).
    pub const DONE: Refinement = Refinement {
        done: true,
        steps: 0,
        remaining: None,
    };
}

/// A global-illumination method. Precomputation ([`Technique::prepare`], then optionally
/// [`Technique::refine`]) is timed apart from frames ([`Technique::render`]).
pub trait Technique {
    /// A short name for reports.
    fn name(&self) -> &str;

    /// View-independent precomputation for `scene` (form factors, LDC, shadow maps...).
    /// Replaces whatever was prepared before. Every method first checks the scene contract
    /// ([`crate::contract::check`]): a scene without geometry, or beyond f32's precision,
    /// is refused with a [`crate::SceneError`] naming the fault; a scene without light is
    /// prepared and renders black.
    fn prepare(&mut self, scene: Arc<Scene>) -> Result<(), Error>;

    /// Continues a progressive precomputation for about `budget` of wall-clock time, so
    /// that error can be reported against time. Techniques that finish in `prepare` report
    /// [`Refinement::DONE`] (the default).
    fn refine(&mut self, budget: Duration) -> Result<Refinement, Error> {
        let _ = budget;
        Ok(Refinement::DONE)
    }

    /// Renders one frame of the prepared scene. Errors with
    /// [`Error::NotPrepared`] before [`Technique::prepare`].
    fn render(&mut self, frame: &FrameRequest<'_>) -> Result<Image, Error>;

    /// The method's own estimate of its relative error on lit surfaces after
    /// [`Technique::prepare`] (and any refinement): the half-width of a 95 % confidence
    /// interval of the lit-surface mean radiance, largest channel, for methods whose
    /// precomputation is a Monte Carlo estimate that can tell its own spread (the IBRR's
    /// batches of particle paths). `None` (the default) for methods that state none.
    fn stated_error(&self) -> Option<f64> {
        None
    }

    /// The method's own time for the last frame [`Technique::render`] made, measured on
    /// its device apart from the work a harness does around it (drawing the G-buffer,
    /// reading the image back): what an engine hosting the method pays. `None` (the
    /// default) when the technique cannot separate the two; a harness then has only its
    /// wall-clock time of the whole `render`.
    fn device_time(&self) -> Option<DeviceTime> {
        None
    }
}

/// A frame's time measured on the device that ran it ([`Technique::device_time`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeviceTime {
    /// Seconds.
    pub seconds: f64,
    /// How they were measured.
    pub clock: DeviceClock,
}

/// How a [`DeviceTime`] was measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeviceClock {
    /// GPU timestamps written before the frame's first command and after its last.
    Timestamps,
    /// The wall clock from recording the frame to the device's completion of it (an
    /// adapter without timestamp queries, or a CPU adapter, whose timestamps do not time
    /// the work); recording and submission are inside.
    WallAfterWait,
}

impl DeviceClock {
    /// The clock in words, for reports.
    pub fn describe(&self) -> &'static str {
        match self {
            DeviceClock::Timestamps => "GPU timestamps",
            DeviceClock::WallAfterWait => "wall clock from recording to completion",
        }
    }
}

/// The outcome of a comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct MetricValue {
    /// The scalar value.
    pub value: f64,
    /// An optional per-pixel map (row-major, the images' size).
    pub map: Option<Vec<f32>>,
}

/// An image comparison measure.
pub trait Metric {
    /// A short name for reports ("mean-error", "ssim"...).
    fn name(&self) -> &str;
    /// True when smaller values mean closer images.
    fn lower_is_better(&self) -> bool;
    /// Compares `test` against `reference` (the same size).
    fn compare(&self, reference: &Image, test: &Image) -> Result<MetricValue, Error>;
}

/// The time of each stage of a frame, in the order the stages run: the one shape every
/// method's frame timings take (ISR's `PassTimings`, relighting's and the IBRR's
/// `FrameTimings`, the viewer's GPU stage profiler), so a harness or a viewer
/// can list and sum any method's stages without knowing its fields.
pub trait StageTimings {
    /// Each stage's name and time, in order.
    fn stages(&self) -> Vec<(&'static str, std::time::Duration)>;

    /// The sum of the stages.
    fn total_time(&self) -> std::time::Duration {
        self.stages().iter().map(|(_, t)| *t).sum()
    }

    /// The stages as a line for a log: `radiosity 0.41 ms, blur 0.08 ms, ...`.
    fn describe(&self) -> String {
        let stages = self.stages();
        let parts: Vec<String> = stages
            .iter()
            .map(|(name, t)| format!("{name} {:.2} ms", t.as_secs_f64() * 1e3))
            .collect();
        parts.join(", ")
    }
}
