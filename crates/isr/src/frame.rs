//! One ISR frame on the CPU (rayon): the thesis' listing 3 from the coarse buffers on.

use std::time::{Duration, Instant};

use glam::{Vec3, Vec4};
use scene_core::{GBuffer, Image, View};

use crate::geometry::Screen;
use crate::light_senders::LightSenders;
use crate::light_set::LightSet;
use crate::settings::{IsrSettings, Sender};
use crate::{IsrError, blur, lighting, radiosity, upsample};

/// The inputs of a frame: the full-resolution G-buffer, its coarse version (any size; the
/// thesis uses half the resolution, see [`crate::downsample()`]) and the view both were
/// rendered from.
#[derive(Clone, Copy, Debug)]
pub struct IsrInputs<'a> {
    /// The full-resolution G-buffer.
    pub full: &'a GBuffer,
    /// The coarse G-buffer the ISR pass runs on.
    pub coarse: &'a GBuffer,
    /// The view of both.
    pub view: &'a View,
}

/// Time of each pass of a frame: wall clock on the CPU; on the GPU, from timestamp queries
/// where the adapter has them ([`PassTimings::gpu_timestamps`]), else the wall-clock time of
/// submitting each pass alone and waiting for it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PassTimings {
    /// True when the times are GPU timestamps (the passes ran back to back in one
    /// submission).
    pub gpu_timestamps: bool,
    /// Downsampling the G-buffer (only when the frame path does it).
    pub downsample: Duration,
    /// Direct light on the coarse buffer (`Lit` senders only).
    pub senders: Duration,
    /// The ISR + SSAO pass.
    pub radiosity: Duration,
    /// The light-space senders' gather ([`crate::LightSenders`]; zero without them).
    pub light_senders: Duration,
    /// Both blur directions.
    pub blur: Duration,
    /// Bilateral upsampling.
    pub upsample: Duration,
    /// The lighting phase (direct light, shadows, eq. 29).
    pub lighting: Duration,
}

impl PassTimings {
    /// The sum of all passes.
    pub fn total(&self) -> Duration {
        self.downsample
            + self.senders
            + self.radiosity
            + self.light_senders
            + self.blur
            + self.upsample
            + self.lighting
    }
}

/// A frame and its intermediate buffers.
#[derive(Clone, Debug)]
pub struct Frame {
    /// The final image (linear RGB radiance; background black).
    pub image: Image,
    /// The coarse direct radiance used as `Lit` senders (empty otherwise).
    pub senders: Vec<Vec3>,
    /// The ISR pass' output per coarse pixel: indirect `rgb`, accessibility `a` (empty when
    /// ISR and SSAO are off).
    pub radiosity: Vec<Vec4>,
    /// The same after the blur.
    pub blurred: Vec<Vec4>,
    /// The blurred buffer upsampled to full resolution.
    pub upsampled: Vec<Vec4>,
    /// Time per pass.
    pub timings: PassTimings,
}

/// Checks that a G-buffer is well formed: non-zero size, channel lengths matching it, and
/// finite values on every non-background pixel.
pub fn check_gbuffer(which: &'static str, g: &GBuffer) -> Result<(), IsrError> {
    if g.width == 0 || g.height == 0 {
        return Err(IsrError::ZeroSize {
            which,
            width: g.width,
            height: g.height,
        });
    }
    let n = g.width as usize * g.height as usize;
    for (channel, len) in [
        ("albedo", g.albedo.len()),
        ("normal", g.normal.len()),
        ("depth", g.depth.len()),
        ("triangle_id", g.triangle_id.len()),
    ] {
        if len != n {
            return Err(IsrError::BadLength {
                which,
                channel,
                expected: n,
                found: len,
            });
        }
    }
    for i in 0..n {
        if g.is_background(i) {
            continue;
        }
        let bad = if !g.albedo[i].is_finite() {
            Some("albedo")
        } else if !g.normal[i].is_finite() {
            Some("normal")
        } else if !g.depth[i].is_finite() {
            Some("depth")
        } else {
            None
        };
        if let Some(channel) = bad {
            return Err(IsrError::NonFinite {
                which,
                channel,
                x: i as u32 % g.width,
                y: i as u32 / g.width,
            });
        }
    }
    Ok(())
}

/// Renders one frame on the CPU: `Lit` senders (when used), the ISR + SSAO pass, the blur,
/// the bilateral upsampling and the lighting phase. With ISR and SSAO both off this is the
/// DL baseline (direct light and shadows only).
///
/// Errors on invalid settings, zero-size or malformed buffers and non-finite G-buffer data;
/// never returns non-finite pixels.
pub fn render_cpu(
    scene: &LightSet,
    inputs: &IsrInputs<'_>,
    settings: &IsrSettings,
) -> Result<Frame, IsrError> {
    render_cpu_with(scene, inputs, settings, None)
}

/// [`render_cpu`] with light-space senders ([`LightSenders`], made from the same light set
/// and the scene): their one bounce is added to the ISR pass' output before the blur, each
/// surface counted once (its time is [`PassTimings::light_senders`]). Errors when
/// `settings.light_senders` asks for them (with the indirect term on) and none are given.
pub fn render_cpu_with(
    scene: &LightSet,
    inputs: &IsrInputs<'_>,
    settings: &IsrSettings,
    light_senders: Option<&LightSenders>,
) -> Result<Frame, IsrError> {
    settings.validate(scene.extent)?;
    if settings.light_senders > 0 && settings.indirect && light_senders.is_none() {
        return Err(IsrError::InvalidSetting {
            name: "light_senders",
            value: settings.light_senders.to_string(),
            reason: "no light-space senders were given: make them with LightSenders::new and \
                     render with render_cpu_with"
                .into(),
        });
    }
    if settings.light_sender_shadows
        && settings.indirect
        && light_senders.is_some_and(|l| !l.is_empty() && !l.has_rays())
    {
        return Err(IsrError::InvalidSetting {
            name: "light_sender_shadows",
            value: "true".into(),
            reason: "these light-space senders carry no CPU ray-query tree for the shadow \
                     rays (made on the GPU, LightSenders::on_gpu): make them with \
                     LightSenders::new"
                .into(),
        });
    }
    check_gbuffer("full", inputs.full)?;
    check_gbuffer("coarse", inputs.coarse)?;
    let screen = Screen::new(inputs.view);
    let mut t = PassTimings::default();
    let mut frame = Frame {
        image: Image::new(0, 0),
        senders: Vec::new(),
        radiosity: Vec::new(),
        blurred: Vec::new(),
        upsampled: Vec::new(),
        timings: t,
    };
    // Without any light there is nothing to bounce (albedo senders would still glow).
    if !settings.is_direct_only() && scene.has_light() {
        let coarse = inputs.coarse;
        if settings.indirect && settings.sender == Sender::Lit {
            let start = Instant::now();
            frame.senders = lighting::senders(scene, &screen, coarse);
            t.senders = start.elapsed();
        }
        let start = Instant::now();
        let senders = (!frame.senders.is_empty()).then_some(frame.senders.as_slice());
        let radius = settings.radius.world(scene.extent);
        frame.radiosity = radiosity::radiosity(&screen, coarse, senders, settings, radius);
        t.radiosity = start.elapsed();
        if let Some(light) =
            light_senders.filter(|_| settings.indirect && settings.light_senders > 0)
        {
            let start = Instant::now();
            let shadowed = settings.light_sender_shadows;
            light.add_to(
                &mut frame.radiosity,
                inputs.view,
                coarse,
                scene,
                radius,
                shadowed,
            );
            t.light_senders = start.elapsed();
        }
        let start = Instant::now();
        frame.blurred = blur::blur(&screen, coarse, &frame.radiosity, settings);
        t.blur = start.elapsed();
        let start = Instant::now();
        frame.upsampled = upsample::upsample(inputs.full, coarse, &frame.blurred, settings);
        t.upsample = start.elapsed();
    }
    let start = Instant::now();
    let isr = (!frame.upsampled.is_empty()).then_some(frame.upsampled.as_slice());
    frame.image = lighting::compose(scene, &screen, inputs.full, isr, settings);
    t.lighting = start.elapsed();
    frame.timings = t;
    Ok(frame)
}

/// Shorthand for [`render_cpu`] that only returns the image.
pub fn render_image(
    scene: &LightSet,
    inputs: &IsrInputs<'_>,
    settings: &IsrSettings,
) -> Result<Image, IsrError> {
    render_cpu(scene, inputs, settings).map(|f| f.image)
}

/// For callers that time a frame including the downsample.
pub(crate) fn timed<T>(f: impl FnOnce() -> T) -> (T, Duration) {
    let start = Instant::now();
    let v = f();
    (v, start.elapsed())
}

impl scene_core::technique::StageTimings for PassTimings {
    fn stages(&self) -> Vec<(&'static str, Duration)> {
        vec![
            ("downsample", self.downsample),
            ("senders", self.senders),
            ("radiosity", self.radiosity),
            ("light senders", self.light_senders),
            ("blur", self.blur),
            ("upsample", self.upsample),
            ("lighting", self.lighting),
        ]
    }
}

#[cfg(test)]
mod stage_tests {
    use super::*;
    use scene_core::technique::StageTimings;

    #[test]
    fn the_stages_are_every_pass() {
        let ms = Duration::from_millis;
        let t = PassTimings {
            gpu_timestamps: false,
            downsample: ms(1),
            senders: ms(2),
            radiosity: ms(4),
            light_senders: ms(64),
            blur: ms(8),
            upsample: ms(16),
            lighting: ms(32),
        };
        assert_eq!(t.total_time(), t.total());
        assert_eq!(t.total_time(), ms(127));
    }
}
