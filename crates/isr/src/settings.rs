//! The parameters of one ISR frame ([`IsrSettings`]) and of the view-independent shadow
//! maps ([`ShadowSettings`]).

use scene_core::gbuffer::DownsampleMode;
use scene_core::reference::Bounces;

use crate::IsrError;

/// How eq. 25 turns one neighbourhood sample into light arriving at the receiver.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Estimator {
    /// Eq. 25 exactly as published: `L_P(X) = rho_P (2 pi / N) F_PX L_X` with the
    /// differential form factor of eq. 6, `F_PX = cos(theta_P) cos(theta_X) A_X / (pi r^2)`,
    /// and `A_X` the fronto-parallel footprint of one coarse pixel at X's depth (figure 4.4).
    /// The `1/r^2` singularity is guarded by `r^2 >= A_X` (a patch is never closer than its
    /// own size). The `2 pi / N` weight makes the term depend on `N` and on the sampling
    /// radius; it is not an estimate of the one-bounce integral.
    Thesis,
    /// The physically consistent point-to-patch estimator:
    /// `(rho_P / pi) sum L_X cos(theta_P) cos(theta_X) A_X / r^2`, where each of the `N`
    /// samples stands for `1/N` of the screen-space disk it is drawn from, so `A_X` is that
    /// share of the disk projected onto the surface at X. A Monte Carlo estimate of the light
    /// reflected from all surfaces visible inside the disk. The singularity is handled with
    /// the disk form factor `A cos cos / (pi r^2 + A)`, which tends to `cos cos` (at most 1)
    /// as `r -> 0` instead of diverging.
    Patch,
}

/// What radiance a neighbourhood sample sends (`L_X` of eq. 25).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Sender {
    /// The thesis: the RGB of the coarse colour (albedo) buffer, independent of the lights.
    Albedo,
    /// What eq. 25 means physically: the radiance X reflects from direct light,
    /// `albedo_X / pi * E_direct(X)` with shadows, computed by the lighting pass on the
    /// coarse buffer before the ISR pass.
    Lit,
}

/// The blur of the coarse ISR/SSAO buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Blur {
    /// Separable Gaussian (the thesis). Background pixels (the stencil mask) take no part.
    Gaussian,
    /// Separable Gaussian whose taps are also weighted by how close each tap lies to the
    /// centre pixel's tangent plane and how well the normals agree, so indirect light does
    /// not bleed across depth discontinuities.
    EdgeAware,
}

/// The world-space radius of the neighbourhood the samples are drawn from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Radius {
    /// A fraction of the scene's extent (the diagonal of its bounds): the same picture
    /// whatever the scene's unit.
    Relative(f32),
    /// World units (metres).
    World(f32),
}

impl Radius {
    /// The radius in world units for a scene of `extent`.
    pub fn world(self, extent: f32) -> f32 {
        match self {
            Radius::Relative(r) => r * extent,
            Radius::World(r) => r,
        }
    }
}

/// The parameters of one frame of image-space radiosity.
///
/// The defaults are the method's physical estimate, with no free scale: the physically
/// sound reading of eq. 25 (`Patch` estimator, `Lit` senders, `k_dl = 1`: see
/// [`IsrSettings::k_dl`]), 80 screen-space samples (section 5.3.1) and about
/// [`DEFAULT_LIGHT_SENDERS`] light-space senders (the surfaces the lights reach first, on
/// screen or not: [`crate::light_senders`]), each surface counted once, `k_isr` 1, Gaussian
/// blur, radius half the scene's extent, no ambient occlusion. On held-out views (`cargo
/// xtask sweep-isr`, seeded random cameras the main job does not score) and on the main
/// job's 12 views it is closer to the bounce-1 reference than direct light on every view
/// (`docs/isr.md`). The light-space senders are made from the scene
/// ([`crate::LightSenders::new`]): [`crate::IsrTechnique`] makes them itself; a host
/// drawing its own frames hands them to [`crate::IsrFrame::with_light_senders`] or
/// [`crate::GpuIsr::set_light_senders`], or, with no scene to make them from, runs
/// [`IsrSettings::screen_space`].
///
/// [`IsrSettings::screen_space`] is the screen-space estimator alone with its measured
/// scale (`k_isr` 4, which puts back light the screen-space disk cannot see: senders
/// outside it or off screen); [`IsrSettings::for_samples`] has that scale at other sample
/// counts. The thesis' constants (`k_ssao = k_isr = 0.5`, AO on, section 4.7) are
/// [`IsrSettings::thesis_constants`], and the thesis as published is
/// [`IsrSettings::thesis`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IsrSettings {
    /// Compute the indirect (ISR) term. Off together with `ssao` this is the DL baseline.
    pub indirect: bool,
    /// Compute screen-space ambient occlusion (eq. 26).
    pub ssao: bool,
    /// Neighbourhood samples per coarse pixel, `N` (the thesis used 24, 48 and 80); 1..=256.
    pub samples: u32,
    /// How a sample turns into light (eq. 25).
    pub estimator: Estimator,
    /// What a sample sends.
    pub sender: Sender,
    /// Radius of the sampled neighbourhood.
    pub radius: Radius,
    /// Blur of the coarse buffer.
    pub blur: Blur,
    /// Blur taps on each side of the centre (0 disables the blur); at most 16.
    pub blur_radius: u32,
    /// Standard deviation of the blur's Gaussian, in coarse pixels.
    pub blur_sigma: f32,
    /// Guard of the bilateral weight `1 / |z_p - z_i|` (eq. 27), relative to the target
    /// pixel's depth: the weight is `1 / max(|z_p - z_i|, eps * z_p)`, so equal depths give a
    /// large finite weight.
    pub upsample_epsilon: f32,
    /// Exponent of the optional normal weight `max(n_p . n_i, 0)^k` of the bilateral
    /// upsampling (0 turns it off, as in the thesis).
    pub upsample_normal_power: f32,
    /// Scale of the direct light (eq. 29). In the thesis `k_dl` is the direct lighting
    /// computed in listing 7 (times the shadow factor); here that lighting is computed
    /// physically (`albedo / pi * E`) and `k_dl` scales it. 1 keeps it physical; only `k_ssao`
    /// and `k_isr` are the 0.5 constants of section 4.7.
    pub k_dl: f32,
    /// Ambient occlusion power in [0, 1] (eq. 29): the occluded term is multiplied by
    /// `saturate(accessibility + 1 - k_ssao)`.
    pub k_ssao: f32,
    /// Indirect light power (eq. 29), at least 0.
    pub k_isr: f32,
    /// Apply ambient occlusion to the indirect term only instead of to the direct term (the
    /// thesis darkens the direct term, which shadows already account for).
    pub ao_indirect_only: bool,
    /// How the coarse buffers are made from the full-resolution G-buffer (scene-core's one
    /// downsampling). [`DownsampleMode::NearestSurface`] by default: the foreground at
    /// silhouettes, averaged inside surfaces; the thesis averages every sample
    /// ([`DownsampleMode::Average`]), which invents surfaces at silhouettes.
    pub downsample: DownsampleMode,
    /// About this many light-space senders ([`crate::light_senders`], reflective shadow
    /// maps: the surfaces each light reaches first, so that lit surfaces off screen send
    /// their bounce too); [`DEFAULT_LIGHT_SENDERS`] by default, 0 for screen-space senders
    /// alone ([`IsrSettings::screen_space`]). With them, `k_isr` 1 is the unscaled
    /// estimate. A frame with a setting above 0 needs the senders handed to it (the CPU's
    /// [`crate::render_cpu_with`], the GPU's [`crate::GpuIsr::set_light_senders`]); without them it
    /// is refused by name.
    pub light_senders: u32,
    /// Shadow the light-space senders' light: one occlusion ray per receiver and sender
    /// (off by default; a measurement of the leaks the missing visibility lets through,
    /// not a real-time setting).
    pub light_sender_shadows: bool,
    /// The bounces the light-space senders carry ([`crate::LightSenders::with_bounces`]):
    /// `Limited(1)` (the default) for one bounce, the thesis' scope; more adds light paths
    /// continued from the first senders, so that surfaces the light reaches second, third
    /// and so on send their light too ([`Bounces::Unlimited`] until Russian roulette ends
    /// them). Without light-space senders this changes nothing.
    pub light_sender_bounces: Bounces,
}

impl Default for IsrSettings {
    fn default() -> Self {
        Self {
            k_isr: 1.0,
            light_senders: DEFAULT_LIGHT_SENDERS,
            ..Self::screen_space()
        }
    }
}

/// About this many light-space senders by default ([`IsrSettings::light_senders`]): the
/// main job's `isr-N` setting, whose error and cost per scene `docs/isr.md` gives.
pub const DEFAULT_LIGHT_SENDERS: u32 = 4096;

impl IsrSettings {
    /// The screen-space estimator alone (no light-space senders) at 80 samples, with the
    /// scale measured on held-out views (`k_isr` 4, [`IsrSettings::k_isr_for_samples`]): the
    /// default before light-space senders, and what a host with a G-buffer but no scene to
    /// make light-space senders from can run.
    pub fn screen_space() -> Self {
        Self {
            indirect: true,
            ssao: false,
            samples: 80,
            estimator: Estimator::Patch,
            sender: Sender::Lit,
            radius: Radius::Relative(0.5),
            blur: Blur::Gaussian,
            blur_radius: 4,
            blur_sigma: 2.0,
            upsample_epsilon: 1e-3,
            upsample_normal_power: 0.0,
            k_dl: 1.0,
            k_ssao: 0.5,
            k_isr: 4.0,
            ao_indirect_only: false,
            downsample: DownsampleMode::NearestSurface,
            light_senders: 0,
            light_sender_shadows: false,
            light_sender_bounces: Bounces::Limited(1),
        }
    }

    /// The thesis' configuration: eq. 25 as published with albedo senders and the thesis'
    /// constants ([`IsrSettings::thesis_constants`]).
    pub fn thesis() -> Self {
        Self {
            estimator: Estimator::Thesis,
            sender: Sender::Albedo,
            ..Self::thesis_constants()
        }
    }

    /// The screen-space estimator with the thesis' constants of section 4.7: `k_isr = k_ssao
    /// = 0.5` with ambient occlusion on, radius a quarter of the extent (the defaults before
    /// they were measured).
    pub fn thesis_constants() -> Self {
        Self {
            ssao: true,
            k_ssao: 0.5,
            k_isr: 0.5,
            radius: Radius::Relative(0.25),
            ..Self::screen_space()
        }
    }

    /// `samples` screen-space samples and about `light_senders` light-space senders, each
    /// surface counted once and nothing scaled (`k_isr` 1): the estimate the two sender
    /// sets make together.
    pub fn with_light_senders(samples: u32, light_senders: u32) -> Self {
        Self {
            samples,
            k_isr: 1.0,
            light_senders,
            ..Self::default()
        }
    }

    /// The measured most accurate `k_isr` for `samples` samples per coarse pixel at the
    /// default radius, from `cargo xtask sweep-isr` on held-out views (128x96, 512-spp
    /// bounce-1 references, 4 seeded random cameras of each built-in scene, seed 7001, none
    /// of them a view the main job scores; no AO, radius 0.5 of the extent): 7 at 24
    /// samples, 5 at 48, 4 at 80, linear in between and held outside. The patch estimator's
    /// near-field guard weighs more with fewer samples (each stands for a larger share of
    /// the disk), so fewer samples need more scale.
    pub fn k_isr_for_samples(samples: u32) -> f32 {
        const MEASURED: [(f32, f32); 3] = [(24.0, 7.0), (48.0, 5.0), (80.0, 4.0)];
        let n = samples as f32;
        if n <= MEASURED[0].0 {
            return MEASURED[0].1;
        }
        for w in MEASURED.windows(2) {
            let ((n0, k0), (n1, k1)) = (w[0], w[1]);
            if n <= n1 {
                return k0 + (k1 - k0) * (n - n0) / (n1 - n0);
            }
        }
        MEASURED[2].1
    }

    /// The screen-space estimator ([`IsrSettings::screen_space`]) at `samples` samples with
    /// the measured best `k_isr` for that count ([`IsrSettings::k_isr_for_samples`]).
    pub fn for_samples(samples: u32) -> Self {
        Self {
            samples,
            k_isr: Self::k_isr_for_samples(samples),
            ..Self::screen_space()
        }
    }

    /// The DL baseline of the thesis (`I_DL`): the same pipeline with ISR and SSAO off (and
    /// no light-space senders to make).
    pub fn dl() -> Self {
        Self {
            indirect: false,
            ssao: false,
            ..Self::screen_space()
        }
    }

    /// True when neither the indirect term nor AO is computed (the coarse passes are
    /// skipped).
    pub fn is_direct_only(&self) -> bool {
        !self.indirect && !self.ssao
    }

    /// Checks every parameter; `extent` is the scene's extent for the relative radius.
    pub fn validate(&self, extent: f32) -> Result<(), IsrError> {
        let bad = |name: &'static str, value: String, reason: &str| {
            Err(IsrError::InvalidSetting {
                name,
                value,
                reason: reason.into(),
            })
        };
        if !(1..=MAX_SAMPLES).contains(&self.samples) {
            return bad(
                "samples",
                self.samples.to_string(),
                "must be in 1..=256 (the thesis used 24, 48, 80)",
            );
        }
        let r = self.radius.world(extent);
        if !(r.is_finite() && r > 0.0) {
            return bad(
                "radius",
                format!("{:?}", self.radius),
                "must give a positive finite world radius",
            );
        }
        if self.light_senders > crate::light_senders::MAX_LIGHT_SENDERS {
            return bad(
                "light_senders",
                self.light_senders.to_string(),
                "at most 65536",
            );
        }
        if self.blur_radius > MAX_BLUR_RADIUS {
            return bad("blur_radius", self.blur_radius.to_string(), "at most 16");
        }
        if !(self.blur_sigma.is_finite() && self.blur_sigma > 0.0) {
            return bad(
                "blur_sigma",
                self.blur_sigma.to_string(),
                "must be positive",
            );
        }
        if !(self.upsample_epsilon.is_finite() && self.upsample_epsilon > 0.0) {
            return bad(
                "upsample_epsilon",
                self.upsample_epsilon.to_string(),
                "must be positive (it guards 1/|dz|)",
            );
        }
        if !(self.upsample_normal_power.is_finite() && self.upsample_normal_power >= 0.0) {
            return bad(
                "upsample_normal_power",
                self.upsample_normal_power.to_string(),
                "must be finite and >= 0",
            );
        }
        if !(self.k_dl.is_finite() && self.k_dl >= 0.0) {
            return bad("k_dl", self.k_dl.to_string(), "must be finite and >= 0");
        }
        if !(0.0..=1.0).contains(&self.k_ssao) {
            return bad("k_ssao", self.k_ssao.to_string(), "must be in [0, 1]");
        }
        if !(self.k_isr.is_finite() && self.k_isr >= 0.0) {
            return bad("k_isr", self.k_isr.to_string(), "must be finite and >= 0");
        }
        Ok(())
    }
}

/// Largest [`IsrSettings::samples`].
pub const MAX_SAMPLES: u32 = 256;
/// Largest [`IsrSettings::blur_radius`].
pub const MAX_BLUR_RADIUS: u32 = 16;

pub use scene_core::shadowed_lights::ShadowSettings;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_bad_values_are_named() {
        IsrSettings::default().validate(1.0).unwrap();
        IsrSettings::dl().validate(1.0).unwrap();
        ShadowSettings::default().validate().unwrap();
        let e = IsrSettings {
            samples: 0,
            ..Default::default()
        }
        .validate(1.0)
        .unwrap_err();
        assert!(e.to_string().contains("samples"), "{e}");
        let e = IsrSettings {
            k_ssao: f32::NAN,
            ..Default::default()
        }
        .validate(1.0)
        .unwrap_err();
        assert!(e.to_string().contains("k_ssao"), "{e}");
        assert!(
            IsrSettings {
                radius: Radius::World(-1.0),
                ..Default::default()
            }
            .validate(1.0)
            .is_err()
        );
        assert!(
            ShadowSettings {
                esm_exponent: f32::INFINITY,
                ..Default::default()
            }
            .validate()
            .is_err()
        );
    }
}
