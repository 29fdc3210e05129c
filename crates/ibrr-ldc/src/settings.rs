//! Settings of construction and reconstruction, with the paper's defaults.

use crate::error::IbrrError;

/// How an IRPL's render becomes LDC values (section 4.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Splat {
    /// The paper's method: each hemicube sample's value is copied to the LDI pixels its
    /// footprint covers; in each layer the copy of the nearest sample wins.
    Nearest,
    /// The kernel the paper planned (section 6.2): each sample's value weighted by a
    /// Gaussian of its footprint over three standard deviations, normalised per layer.
    Gaussian,
    /// Beyond the paper: the geometry term is evaluated at every LDI pixel centre, the
    /// renders deciding only visibility; samples create the layers over their footprints,
    /// and every layer no sample reached is lit when no rendered surface lies between the
    /// IRPL and its centre (the renders as a shadow map of planes).
    Exact,
}

impl std::str::FromStr for Splat {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "nearest" => Ok(Splat::Nearest),
            "gaussian" => Ok(Splat::Gaussian),
            "exact" => Ok(Splat::Exact),
            _ => Err(format!(
                "splat must be 'nearest', 'gaussian' or 'exact', got '{s}'"
            )),
        }
    }
}

impl std::str::FromStr for Compensation {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "local" => Ok(Compensation::Local),
            "rescale" => Ok(Compensation::Rescale),
            _ => Err(format!(
                "compensation must be 'local' or 'rescale', got '{s}'"
            )),
        }
    }
}

/// How a camera pixel reads the LDC (section 5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lookup {
    /// The LDI pixel the point falls in.
    Nearest,
    /// The mean of matching layers in a `(2 radius + 1)^2` block (the paper's averaging
    /// kernel).
    Average {
        /// Half-width of the block in LDI pixels.
        radius: u32,
    },
    /// Bilinear over the four nearest LDI pixel centres, blended across LDIs near their
    /// boundaries (section 6.2).
    Bilinear,
}

impl std::str::FromStr for Lookup {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "nearest" => Ok(Lookup::Nearest),
            "average" => Ok(Lookup::Average { radius: 1 }),
            "bilinear" => Ok(Lookup::Bilinear),
            _ => Err(format!(
                "lookup must be 'nearest', 'average' or 'bilinear', got '{s}'"
            )),
        }
    }
}

/// Everything that shapes an IBRR.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IbrrSettings {
    /// LDI resolution along each side of the bounding cube (paper: 128 to 512).
    pub resolution: u32,
    /// About this many IRPLs (paper: 184): exact sources, plus as many particle paths as a
    /// pilot walk says give the rest on average. With [`IbrrSettings::target_error`], the
    /// first round's count.
    pub irpls: u32,
    /// The relative error on lit surfaces a build aims at (the half-width of the 95 %
    /// confidence interval of the lit-surface mean radiance, largest channel, from the
    /// build's own batches: [`crate::estimate`]). Construction adds rounds of paths until
    /// its estimate is below this, or [`IbrrSettings::irpl_budget`] or
    /// [`IbrrSettings::time_budget`] would be exceeded
    /// ([`crate::Construction::stopped`] says which). 0: exactly the paths `irpls` asks
    /// for, the paper's fixed count (its Table 1).
    pub target_error: f32,
    /// Most IRPLs a build aiming at [`IbrrSettings::target_error`] makes; 0 (the
    /// default): twice `irpls`, which keeps a build within about twice the time of the
    /// fixed count ([`IbrrSettings::budget`]).
    pub irpl_budget: u32,
    /// Seconds after which a build aiming at [`IbrrSettings::target_error`] adds no
    /// further round (checked between rounds; 0: no limit). A build stopped by time
    /// depends on the machine's speed; the IRPL budget does not.
    pub time_budget: f32,
    /// Number of particle paths; `0` (the default): derived from `irpls` by a pilot walk.
    /// Fixing it keeps the same paths when the geometry is cut differently.
    pub paths: u32,
    /// Hemicube resolution of the first node of each path (direct light); `0`: the LDC
    /// resolution, as in the paper's Table 1.
    pub direct_hemicube: u32,
    /// Hemicube resolution of later nodes (section 4.1 lowers it); `0`: half the direct one.
    pub indirect_hemicube: u32,
    /// Splat kernel.
    pub splat: Splat,
    /// Clamp of the geometry term of path IRPLs, as a distance: `g <= 1 / (pi (clamp x
    /// extent)^2)`; 0 (the default) leaves it unclamped, the paper's accurate option. With
    /// a clamp, each IRPL's contributions are scaled so that the power its renders receive
    /// is what it was unclamped (bias compensation: the clamped energy is restored over what
    /// the IRPL lights, not at the hot spot). Beyond the paper.
    pub clamp: f32,
    /// Reconstruction kernel.
    pub lookup: Lookup,
    /// Plane-distance threshold in LDI pixels.
    pub eps_distance_px: f32,
    /// Normal threshold: layers match when `n' . n > 1 - eps_normal`.
    pub eps_normal: f32,
    /// Normals within this of the dominant component also go to the other LDIs (the blend
    /// across LDIs).
    pub band: f32,
    /// Largest splat radius in LDI pixels (grazing samples).
    pub max_splat_px: f32,
    /// Pixels with no matching layer search this many LDI pixels around them.
    pub fallback_radius: u32,
    /// Pixels that find no layer even by the fallback take the light of the camera pixels
    /// around them that did, up to this many camera pixels away (the hole fill,
    /// [`crate::reconstruct()`]); 0 leaves them black.
    pub fill_radius: u32,
    /// Seed of the particle walks.
    pub seed: u64,
    /// Most bounces of a particle.
    pub max_depth: u32,
    /// Spend the IRPL budget on the light the scene's cameras see
    /// ([`crate::irpl::WalkSettings::camera_importance`]); off: every surface alike.
    pub camera_importance: bool,
    /// Start suns' and sky regions' particles where their light enters what the scene's
    /// cameras see ([`crate::irpl::EntryImportance`]; unbiased; no effect without cameras
    /// or directional light).
    pub entry_importance: bool,
    /// Memory budget of the LDC in bytes (construction fails with a typed error before
    /// exceeding it).
    pub max_bytes: u64,
    /// How each layer's light per source is stored (f32, or f16 at half the memory).
    pub source_precision: crate::ldc::SourcePrecision,
    /// How the energy the clamp removes is given back (with `clamp > 0`).
    pub compensation: Compensation,
    /// Rays a layer for [`Compensation::Local`].
    pub compensation_rays: u32,
    /// Levels of [`Compensation::Local`]: 1 recovers the clamped light, each further level
    /// the clamped part of what was recovered.
    pub compensation_levels: u32,
}

/// How the energy the clamp removes is given back.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Compensation {
    /// Where it was lost: short rays from every layer find the surfaces within the clamp's
    /// reach and add the part of their light the clamp removed ([`crate::compensate`],
    /// after Kollig and Keller).
    #[default]
    Local,
    /// Each IRPL's values scaled so that the power its renders receive is what it was
    /// unclamped: the energy kept, but spread over everything the IRPL lights (a global
    /// rescale, kept for comparison).
    Rescale,
}

impl Default for IbrrSettings {
    fn default() -> Self {
        Self {
            resolution: 256,
            irpls: 184,
            target_error: 0.02,
            irpl_budget: 0,
            time_budget: 0.0,
            paths: 0,
            direct_hemicube: 0,
            indirect_hemicube: 0,
            splat: Splat::Exact,
            clamp: 0.1,
            lookup: Lookup::Bilinear,
            eps_distance_px: 0.5,
            eps_normal: 0.05,
            band: 0.1,
            max_splat_px: 16.0,
            fallback_radius: 4,
            fill_radius: 16,
            seed: 1,
            max_depth: 32,
            camera_importance: false,
            entry_importance: false,
            max_bytes: 2 << 30,
            source_precision: crate::ldc::SourcePrecision::F32,
            compensation: Compensation::Local,
            compensation_rays: 16,
            compensation_levels: 2,
        }
    }
}

/// Largest [`IbrrSettings::fill_radius`] (camera pixels): a hole pixel reads at most
/// `(2 r + 1)^2` neighbours.
pub const MAX_FILL_RADIUS: u32 = 64;

/// How a frame reads the LDC: the kernel, the fallback's reach in LDI pixels and the hole
/// fill's in camera pixels ([`crate::reconstruct()`], [`crate::GpuLdc::new`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reading {
    /// Reconstruction kernel.
    pub lookup: Lookup,
    /// [`IbrrSettings::fallback_radius`].
    pub fallback_radius: u32,
    /// [`IbrrSettings::fill_radius`].
    pub fill_radius: u32,
}

impl Reading {
    /// `lookup` with the default fallback and fill.
    pub fn with_lookup(lookup: Lookup) -> Self {
        Self {
            lookup,
            ..IbrrSettings::default().reading()
        }
    }
}

impl IbrrSettings {
    /// How frames read the LDC built with these settings.
    pub fn reading(&self) -> Reading {
        Reading {
            lookup: self.lookup,
            fallback_radius: self.fallback_radius,
            fill_radius: self.fill_radius,
        }
    }

    /// The direct hemicube resolution in effect.
    pub fn direct_resolution(&self) -> u32 {
        if self.direct_hemicube == 0 {
            self.resolution
        } else {
            self.direct_hemicube
        }
    }

    /// The IRPL budget in effect ([`IbrrSettings::irpl_budget`], 0 read as twice
    /// `irpls`).
    pub fn budget(&self) -> u32 {
        if self.irpl_budget == 0 {
            self.irpls.saturating_mul(2)
        } else {
            self.irpl_budget
        }
    }

    /// The paper's fixed IRPL count: these settings without an error target.
    pub fn fixed_count(self) -> Self {
        Self {
            target_error: 0.0,
            ..self
        }
    }

    /// The indirect hemicube resolution in effect.
    pub fn indirect_resolution(&self) -> u32 {
        if self.indirect_hemicube == 0 {
            self.direct_resolution().div_ceil(2).max(1)
        } else {
            self.indirect_hemicube
        }
    }

    /// Checks every setting, naming the first one out of range.
    pub fn check(&self) -> Result<(), IbrrError> {
        let bad = |m: String| Err(IbrrError::Settings(m));
        if self.resolution == 0 || self.resolution > 16384 {
            return bad(format!(
                "resolution must be in 1..=16384, got {}",
                self.resolution
            ));
        }
        if !(1..=10_000_000).contains(&self.irpls) || self.paths > 10_000_000 {
            return bad(format!(
                "irpls must be in 1..=10^7 (none lights nothing) and paths at most 10^7, got {} \
                 and {}",
                self.irpls, self.paths
            ));
        }
        if !(0.0..=1.0).contains(&self.target_error) {
            return bad(format!(
                "target_error must be in [0, 1] (0: the fixed IRPL count), got {}",
                self.target_error
            ));
        }
        if self.irpl_budget != 0 && !(self.irpls..=10_000_000).contains(&self.irpl_budget) {
            return bad(format!(
                "irpl_budget must be 0 (twice irpls) or in irpls..=10^7 ({}..=10^7), got {}",
                self.irpls, self.irpl_budget
            ));
        }
        if !(self.time_budget >= 0.0 && self.time_budget <= 1e6) {
            return bad(format!(
                "time_budget must be in [0, 10^6] seconds (0: none), got {}",
                self.time_budget
            ));
        }
        if self.direct_resolution() > 8192 || self.indirect_resolution() > 8192 {
            return bad("hemicube resolutions must be at most 8192".into());
        }
        if !(self.eps_distance_px > 0.0 && self.eps_distance_px.is_finite()) {
            return bad(format!(
                "eps_distance_px must be positive, got {}",
                self.eps_distance_px
            ));
        }
        if !(self.eps_normal > 0.0 && self.eps_normal < 2.0) {
            return bad(format!(
                "eps_normal must be in (0, 2), got {}",
                self.eps_normal
            ));
        }
        if !(0.0..=1.0).contains(&self.clamp) {
            return bad(format!(
                "clamp must be in [0, 1] (a fraction of the scene's extent), got {}",
                self.clamp
            ));
        }
        if !(0.0..1.0).contains(&self.band) {
            return bad(format!("band must be in [0, 1), got {}", self.band));
        }
        if !(self.max_splat_px >= 0.5 && self.max_splat_px <= 64.0) {
            return bad(format!(
                "max_splat_px must be in [0.5, 64], got {}",
                self.max_splat_px
            ));
        }
        if let Lookup::Average { radius } = self.lookup
            && radius > 16
        {
            return bad(format!("averaging radius must be at most 16, got {radius}"));
        }
        if !(1..=8).contains(&self.compensation_levels) {
            return bad(format!(
                "compensation_levels must be in 1..=8, got {}",
                self.compensation_levels
            ));
        }
        if self.compensation_rays > 4096 {
            return bad(format!(
                "compensation_rays must be at most 4096, got {}",
                self.compensation_rays
            ));
        }
        if self.fallback_radius > 64 {
            return bad(format!(
                "fallback_radius must be at most 64, got {}",
                self.fallback_radius
            ));
        }
        if self.fill_radius > MAX_FILL_RADIUS {
            return bad(format!(
                "fill_radius must be at most {MAX_FILL_RADIUS}, got {}",
                self.fill_radius
            ));
        }
        Ok(())
    }
}
