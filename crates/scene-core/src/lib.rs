//! # scene-core
//!
//! The vocabulary every crate of the diffuse-GI toolkit speaks: the [`Scene`] model, [`View`]s
//! (cameras, hemicube faces, shadow maps), the [`GBuffer`], the [`Technique`] and [`Metric`]
//! traits, ray queries over a four-wide BVH, sampling, linear-RGB images, a headless GPU context and
//! the ground-truth [`reference`](mod@reference) path tracer.
//!
//! ```
//! use scene_core::{builtin, reference::{self, Bounces, ReferenceSettings}, View};
//!
//! let scene = builtin::scene("cornell").unwrap();
//! let camera = scene.cameras[0].clone();
//! let settings = ReferenceSettings { width: 16, height: 16, spp: 4, bounces: Bounces::Limited(1), seed: 7 };
//! let out = reference::render(&scene, &View::from_camera(&camera), &settings, None);
//! assert_eq!(out.image.pixels.len(), 256);
//! assert!(out.image.pixels.iter().all(|p| p.is_finite()));
//! ```

//! ## Layers
//!
//! | layer | modules | what lives there |
//! |---|---|---|
//! | scene model | [`model`]: [`scene`], [`builtin`], [`lights`], [`view`] | meshes, materials, lights and their ids and state, cameras and views |
//! | files | [`files`]: [`gltf_io`], [`image`], [`budget`] | glTF, EXR and PNG in and out, budgets against hostile files |
//! | rays | [`rays`]: [`ray`], [`reference`](mod@reference), [`sampling`] | the BVH, the reference path tracer, sampling |
//! | direct light | [`shadowed_lights`] (with [`shadowed_lights::esm`]) | lights with exponential shadow maps, evaluated per pixel by ISR and relighting (CPU and WGSL) |
//! | G-buffer | [`gbuffer`] (with [`gbuffer::downsample`](mod@gbuffer::downsample)) | the currency of the screen-space methods, the renderer trait, operations on G-buffers (CPU and WGSL) |
//! | GPU | [`gpu`] (with [`gpu::compute`]) | the headless context, uploads and readbacks, GPU G-buffers, the compute-pass helper and pass timer |
//! | methods | [`technique`], [`error`], [`hash`], [`range`] | the traits the methods implement, errors, scene identity, stated ranges of user-set numbers |
//!
//! Each module of a layer is also reachable at the crate root (`scene_core::scene`,
//! `scene_core::gltf_io`, ...), the paths the rest of the workspace uses.

pub mod error;
pub mod files;
pub mod gbuffer;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod hash;
pub mod model;
pub mod range;
pub mod rays;
#[cfg(feature = "rays")]
pub mod shadowed_lights;
pub mod technique;
#[cfg(feature = "testing")]
pub mod testing;

pub use cutout::Cutouts;
#[cfg(feature = "gltf")]
pub use files::gltf_io;
pub use files::open::{AddedLights, OpenError, OpenedScene, open_scene, open_scene_with};
pub use files::{budget, image};
pub use model::{builtin, contract, cutout, lights, scene, sky, view};
#[cfg(feature = "rays")]
pub use rays::ray;
pub use rays::{reference, sampling};

pub use budget::{Budget, BudgetError};
pub use error::{BudgetExceeded, GltfError, ImageError, SceneError};
pub use gbuffer::{
    BACKGROUND_ID, GBuffer, GBufferRenderer, HemicubeFaceBuffer, ViewTarget, hemicube_views,
};
pub use image::{Image, luminance};
pub use lights::{InvalidLightSetting, LightId, LightSetting, LightState, UnknownLight};
pub use scene::{
    Bounds, Camera, DirectionalLight, Material, Mesh, PointLight, Sampler, Scene, Texture, Wrap,
};
pub use technique::{
    DeviceClock, DeviceTime, FrameRequest, Metric, MetricValue, Refinement, StageTimings, Technique,
};
pub use view::{DepthConvention, FrustumCorners, HemicubeFace, Projection, View};

pub use glam;

/// Every shader pass of scene-core, as `cargo xtask shaders` validates them. Each crate keeps
/// its registry at its root, `<crate>::SHADER_PASSES` (here since 2026-11-27; it was in
/// `gpu.rs`, below the modules it lists).
#[cfg(feature = "gpu")]
pub const SHADER_PASSES: &[gpu::shader::ShaderPass] = &[
    #[cfg(feature = "testing")]
    crate::testing::DEPTH_FROM_VALUES,
    crate::gbuffer::downsample::DOWNSAMPLE,
    gpu::host::HOST_GBUFFER,
    gpu::frame::PIXELS_TO_TEXTURE,
    gpu::frame::PIXELS_TO_TEXTURE_RGBA16F,
    crate::shadowed_lights::gpu_maps::SHADOW_MAPS,
    #[cfg(feature = "reference")]
    crate::reference::PATH_TRACER,
];

/// Any error of the toolkit's shared layer.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The scene is invalid.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A glTF file could not be read or written.
    #[error(transparent)]
    Gltf(#[from] GltfError),
    /// An image could not be read or written, or sizes do not match.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// The GPU is missing or failed.
    #[cfg(feature = "gpu")]
    #[error(transparent)]
    Gpu(#[from] gpu::GpuError),
    /// A file asked for more than its [`budget::Budget`] allows.
    #[error(transparent)]
    FileBudget(#[from] budget::BudgetError),
    /// A budget (memory, element count) would be exceeded.
    #[error("budget exceeded: {0}")]
    Budget(BudgetExceeded),
    /// An argument is out of range.
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// A frame was asked of a technique or renderer before it was prepared for a scene.
    #[error("{0} has not been prepared for a scene (call prepare first)")]
    NotPrepared(String),
    /// An error of one method's crate (ISR, relighting, IBRR...), kept whole: its kind
    /// survives the trait boundary and can be recovered with [`Error::method_error`].
    #[error("{method}: {source}")]
    Method {
        /// The method's short name ("isr", "relight-pr"...).
        method: &'static str,
        /// The method's own error.
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
}

impl Error {
    /// Wraps a method crate's own error, keeping its type.
    pub fn method<E: std::error::Error + Send + Sync + 'static>(
        method: &'static str,
        e: E,
    ) -> Self {
        Error::Method {
            method,
            source: Box::new(e),
        }
    }

    /// The method crate's error of type `E` inside an [`Error::Method`], if that is what
    /// this is.
    pub fn method_error<E: std::error::Error + 'static>(&self) -> Option<&E> {
        match self {
            Error::Method { source, .. } => source.downcast_ref::<E>(),
            _ => None,
        }
    }
}
