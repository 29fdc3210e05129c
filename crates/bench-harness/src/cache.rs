//! Reference images cached on disk, keyed by a hash of the scene, camera, settings and spp.

use std::path::{Path, PathBuf};

use scene_core::reference::{self, ReferenceSettings};
use scene_core::{Camera, Image, LightState, Scene, View};
use serde::{Deserialize, Serialize};

use crate::HarnessError;

/// Bumped when the path tracer's output for the same inputs changes (3: Russian roulette
/// survives with the throughput, no longer capped at 0.95; 4: a pixel's position and its
/// first vertices' emitter points and bounces are stratified, and a uniform sky is found by
/// the bounce alone).
pub const TRACER_VERSION: u32 = 4;

pub use scene_core::hash::Fnv;

/// The scene identity used in cache keys: scene-core's
/// [`scene_content_hash`](scene_core::hash::scene_content_hash) (geometry, materials,
/// textures, lights; not the name or the cameras).
pub use scene_core::hash::scene_content_hash as scene_hash;

/// The cache key of a reference render.
pub fn reference_key(scene_hash: u64, camera: &Camera, settings: &ReferenceSettings) -> u64 {
    let mut h = Fnv::default();
    h.u64(TRACER_VERSION as u64)
        .u64(scene_hash)
        .f32s(camera.position.to_array())
        .f32s(camera.target.to_array())
        .f32s(camera.up.to_array())
        .f32s([camera.fov_y, camera.aspect, camera.near, camera.far])
        .u64(settings.width as u64)
        .u64(settings.height as u64)
        .u64(settings.spp as u64)
        .str(&settings.bounces.to_string())
        .u64(settings.seed);
    h.finish()
}

#[derive(Serialize, Deserialize)]
struct CacheMeta {
    seconds: f64,
    spp: u32,
    scene: String,
    camera: String,
    bounces: String,
}

/// A reference render: the image and the seconds its sampling took (the renderer's own
/// preparation, such as uploading the scene, left out).
#[derive(Clone, Debug)]
pub struct RenderedReference {
    /// The mean radiance per pixel.
    pub image: Image,
    /// Seconds of the sampling.
    pub seconds: f64,
}

/// What renders the references and the equal-error ladder: the CPU path tracer, the
/// definition (the default, [`CpuReference`]), or a twin of its estimator on another device
/// (the GPU path tracer, supplied by a composition point such as `xtask experiment --gpu`),
/// whose ladder then times what that device's path tracer costs.
pub trait ReferenceRenderer: Send + Sync + std::fmt::Debug {
    /// The renderer in words, for reports (`cpu`, `gpu: NVIDIA H200 (Vulkan)`).
    fn describe(&self) -> String;

    /// A tag in the cache keys of its renders: renderers whose images differ for the same
    /// seed (another random number sequence) must tag differently. The CPU tracer's is empty,
    /// keeping the keys of caches made before renderers existed.
    fn key_tag(&self) -> &str;

    /// Renders `view` of `scene` under `lights`; `progress(rows_done, rows)` follows it.
    fn render(
        &self,
        scene: &Scene,
        view: &View,
        settings: &ReferenceSettings,
        lights: &LightState,
        progress: Option<&(dyn Fn(u64, u64) + Sync)>,
    ) -> Result<RenderedReference, HarnessError>;
}

/// The CPU path tracer ([`reference::render_lit`]) as a [`ReferenceRenderer`].
#[derive(Clone, Copy, Debug, Default)]
pub struct CpuReference;

impl ReferenceRenderer for CpuReference {
    fn describe(&self) -> String {
        "the CPU path tracer".into()
    }

    fn key_tag(&self) -> &str {
        ""
    }

    fn render(
        &self,
        scene: &Scene,
        view: &View,
        settings: &ReferenceSettings,
        lights: &LightState,
        progress: Option<&(dyn Fn(u64, u64) + Sync)>,
    ) -> Result<RenderedReference, HarnessError> {
        let out = reference::render_lit(scene, view, settings, lights, progress);
        Ok(RenderedReference {
            image: out.image,
            seconds: out.stats.seconds,
        })
    }
}

/// A cached or freshly rendered reference.
#[derive(Clone, Debug)]
pub struct CachedReference {
    /// The image.
    pub image: Image,
    /// Seconds of the render that produced it.
    pub seconds: f64,
    /// Its key.
    pub key: u64,
    /// True when read from the cache.
    pub from_cache: bool,
}

/// A folder of reference renders.
#[derive(Clone, Debug)]
pub struct ReferenceCache {
    dir: PathBuf,
    renderer: std::sync::Arc<dyn ReferenceRenderer>,
}

impl ReferenceCache {
    /// A cache in `dir` (created on the first write) of the CPU path tracer's renders.
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self::with_renderer(dir, std::sync::Arc::new(CpuReference))
    }

    /// A cache in `dir` of `renderer`'s renders (its [`ReferenceRenderer::key_tag`] is part
    /// of every key, so renderers share a folder without mixing).
    pub fn with_renderer(
        dir: impl Into<PathBuf>,
        renderer: std::sync::Arc<dyn ReferenceRenderer>,
    ) -> Self {
        Self {
            dir: dir.into(),
            renderer,
        }
    }

    /// What renders this cache's misses.
    pub fn renderer(&self) -> &dyn ReferenceRenderer {
        self.renderer.as_ref()
    }

    /// The cache folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The reference of `camera` (its aspect as given) from the cache, or rendered with
    /// `settings` and stored. `progress(rows_done, rows_total)` follows a render.
    pub fn get_or_render(
        &self,
        scene: &Scene,
        scene_hash: u64,
        camera: &Camera,
        settings: &ReferenceSettings,
        progress: Option<&(dyn Fn(u64, u64) + Sync)>,
    ) -> Result<CachedReference, HarnessError> {
        self.get_or_render_lit(
            scene,
            scene_hash,
            camera,
            settings,
            &LightState::default(),
            progress,
        )
    }

    /// [`get_or_render`](Self::get_or_render) under a light state (recoloured, dimmed or
    /// switched lights): the state's fingerprint is part of the key, so each frame of a
    /// relighting sequence has its own cached reference.
    pub fn get_or_render_lit(
        &self,
        scene: &Scene,
        scene_hash: u64,
        camera: &Camera,
        settings: &ReferenceSettings,
        lights: &LightState,
        progress: Option<&(dyn Fn(u64, u64) + Sync)>,
    ) -> Result<CachedReference, HarnessError> {
        let mut key = reference_key(scene_hash, camera, settings);
        let tag = self.renderer.key_tag();
        if !tag.is_empty() {
            let mut h = Fnv::default();
            h.u64(key).str(tag);
            key = h.finish();
        }
        if !lights.is_default() {
            let mut h = Fnv::default();
            h.u64(key).u64(lights.fingerprint());
            key = h.finish();
        }
        let exr = self.dir.join(format!("{key:016x}.exr"));
        let meta_path = self.dir.join(format!("{key:016x}.json"));
        let budget = scene_core::Budget::default();
        if let (Ok(image), Ok(text)) = (
            Image::read_exr_with(&exr, &budget),
            scene_core::budget::read_file(&meta_path, &budget),
        ) && let Ok(meta) = serde_json::from_slice::<CacheMeta>(&text)
        {
            // A file read back is checked like user input: a bad entry is rendered again,
            // with a note naming the file.
            match check_entry(&image, &meta, settings) {
                Ok(()) => {
                    return Ok(CachedReference {
                        image,
                        seconds: meta.seconds,
                        key,
                        from_cache: true,
                    });
                }
                Err(why) => eprintln!(
                    "note: reference cache entry {}: {why}; rendering it again",
                    exr.display()
                ),
            }
        }
        let out = self.renderer.render(
            scene,
            &View::from_camera(camera),
            settings,
            lights,
            progress,
        )?;
        let bad = out.image.non_finite_count();
        if bad > 0 {
            return Err(HarnessError::Invalid(format!(
                "the reference render of scene '{}' from '{}' has {bad} non-finite pixel(s); \
                 nothing was cached",
                scene.name, camera.name
            )));
        }
        std::fs::create_dir_all(&self.dir).map_err(|e| HarnessError::io(&self.dir, e))?;
        out.image
            .write_exr(&exr)
            .map_err(|e| HarnessError::from(scene_core::Error::from(e)))?;
        crate::write_json(
            &meta_path,
            &CacheMeta {
                seconds: out.seconds,
                spp: settings.spp,
                scene: scene.name.clone(),
                camera: camera.name.clone(),
                bounces: settings.bounces.to_string(),
            },
        )?;
        Ok(CachedReference {
            image: out.image,
            seconds: out.seconds,
            key,
            from_cache: false,
        })
    }
}

/// What a cache entry read back must hold to be used: the asked size, finite non-negative
/// pixels, and a sidecar whose samples and bounces are the asked ones and whose render time
/// is a time (finite, at least 0, under a year).
fn check_entry(
    image: &Image,
    meta: &CacheMeta,
    settings: &ReferenceSettings,
) -> Result<(), String> {
    if (image.width, image.height) != (settings.width, settings.height) {
        return Err(format!(
            "image is {}x{}, {}x{} asked",
            image.width, image.height, settings.width, settings.height
        ));
    }
    if let Some(i) = image
        .pixels
        .iter()
        .position(|p| !p.is_finite() || p.min_element() < 0.0)
    {
        let w = image.width.max(1) as usize;
        return Err(format!(
            "pixel ({}, {}) is {:?} (not finite or negative)",
            i % w,
            i / w,
            image.pixels[i]
        ));
    }
    if !(meta.seconds.is_finite() && (0.0..3.2e7).contains(&meta.seconds)) {
        return Err(format!(
            "its sidecar's seconds {} is not a render time",
            meta.seconds
        ));
    }
    if meta.spp != settings.spp || meta.bounces != settings.bounces.to_string() {
        return Err(format!(
            "its sidecar says {} spp, bounces {} ({} spp, bounces {} asked)",
            meta.spp, meta.bounces, settings.spp, settings.bounces
        ));
    }
    Ok(())
}
