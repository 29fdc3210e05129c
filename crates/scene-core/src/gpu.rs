//! Headless GPU context (wgpu), scene and image upload, the GPU G-buffer and explicit
//! readback.
//!
//! Everything here is blocking: [`GpuContext::new`] and the `read_*` helpers drive wgpu's
//! futures with `pollster` and `Device::poll`, so callers never see async code. Nothing is
//! cached globally; every [`GpuContext`] owns its own device (and is cheap to clone, all
//! wgpu handles being reference counted).
//!
//! Adapter selection follows wgpu's environment variables:
//!
//! * `WGPU_BACKEND`: comma-separated backends to try (`vulkan`, `gl`, `metal`, `dx12`);
//!   all compiled-in backends when unset.
//! * `WGPU_ADAPTER_NAME`: pick the first adapter whose name contains this (case-insensitive)
//!   substring, e.g. `llvmpipe` for Mesa's lavapipe.
//! * `WGPU_POWER_PREF`: `high` (the default here), `low` or `none`, when no name is given.
//!
//! On a machine without a GPU, Mesa's software Vulkan driver works:
//! `apt-get install mesa-vulkan-drivers libvulkan1` (Debian/Ubuntu).
//!
//! Tests of every crate get their context from `scene_core::testing::gpu_test_context`
//! (feature `testing`), which skips (or, with
//! `REQUIRE_GPU=1`, fails) when no adapter exists.

use std::sync::mpsc;

use bytemuck::Pod;
use glam::{Vec3, Vec4};
use wgpu::util::DeviceExt;

pub mod compute;
pub mod frame;
pub mod host;
pub mod layout;
pub mod raster;
pub mod shader;
pub mod wgsl_layout;
pub use compute::{ComputePass, PassTimer, WORKGROUP};
pub use frame::{
    FrameInputs, FrameWriter, GpuFrame, KeptBuffer, Keyed, ObjectCounts, PixelsToTexture,
    check_frame_target,
};
pub use host::{HostGBuffer, HostGBufferPass, NormalEncoding, SURFACE_WITHOUT_ID};
pub use wgpu::naga;

use crate::gbuffer::GBuffer;
use crate::image::Image;

/// An error of the GPU layer.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter exists for the backends tried.
    #[error(
        "no GPU adapter found (backends tried: {tried}); install a Vulkan driver, e.g. Mesa's \
         lavapipe: apt-get install mesa-vulkan-drivers, or set WGPU_BACKEND/WGPU_ADAPTER_NAME"
    )]
    NoAdapter {
        /// The backends that were tried, e.g. `vulkan, gl`.
        tried: String,
    },
    /// `WGPU_ADAPTER_NAME` is set but matches none of the adapters found.
    #[error(
        "no GPU adapter matches WGPU_ADAPTER_NAME={wanted:?} (adapters found: {available}); \
         unset it or pick one of those names"
    )]
    AdapterNotFound {
        /// The requested name substring.
        wanted: String,
        /// Summaries of the adapters that exist.
        available: String,
    },
    /// The adapter refused to create a device.
    #[error("GPU device request failed: {0}")]
    RequestDevice(String),
    /// A shader did not compose or validate.
    #[error("shader {pass}: {message}")]
    Shader {
        /// The pass ([`shader::ShaderPass::name`]).
        pass: String,
        /// The composer's or naga's report.
        message: String,
    },
    /// Copying or mapping data back to the CPU failed.
    #[error("GPU readback failed: {0}")]
    Readback(String),
    /// A size is zero or exceeds the device's limits.
    #[error("invalid GPU resource size {width}x{height}: {reason}")]
    InvalidSize {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
        /// Why it is invalid.
        reason: String,
    },
    /// CPU data does not have the length its declared size implies.
    #[error("{what} has {found} elements, expected {expected}")]
    BadLength {
        /// Which data.
        what: &'static str,
        /// Expected element count.
        expected: usize,
        /// Actual element count.
        found: usize,
    },
    /// A texture has another format than the operation needs.
    #[error("texture format {found:?} where {expected} was expected")]
    WrongFormat {
        /// The format(s) the operation accepts.
        expected: &'static str,
        /// The texture's format.
        found: wgpu::TextureFormat,
    },
    /// One of an engine's G-buffer textures cannot be read ([`host::HostGBuffer::check`]).
    #[error("the engine's {texture} texture: {problem}")]
    HostTexture {
        /// Which texture: albedo, normal, depth or triangle id.
        texture: &'static str,
        /// What is wrong with it.
        problem: String,
    },
    /// wgpu reported a validation error (a bug in the calling code or a missing usage flag).
    #[error("GPU validation error: {0}")]
    Validation(String),
    /// Data to upload exceeds a limit of the adapter (refused before allocating).
    #[error(transparent)]
    Budget(crate::BudgetExceeded),
}

impl GpuError {
    /// True when the error means "no usable adapter here" (rather than a failure of an
    /// existing one): [`GpuError::NoAdapter`] and [`GpuError::AdapterNotFound`].
    pub fn is_missing_adapter(&self) -> bool {
        matches!(self, Self::NoAdapter { .. } | Self::AdapterNotFound { .. })
    }
}

/// A wgpu device and queue every GPU path of the toolkit runs on: one this crate created
/// ([`GpuContext::new`], headless, with its instance and adapter), or a host engine's own
/// ([`GpuContext::from_device`]).
#[derive(Clone, Debug)]
pub struct GpuContext {
    /// The wgpu instance (backends from `WGPU_BACKEND`); `None` on a host's device.
    pub instance: Option<wgpu::Instance>,
    /// The chosen adapter; `None` on a host's device.
    pub adapter: Option<wgpu::Adapter>,
    /// The device (one this crate made gets the adapter's own limits, not the downlevel
    /// defaults).
    pub device: wgpu::Device,
    /// The device's queue.
    pub queue: wgpu::Queue,
    /// Readbacks made through this context and its clones ([`GpuContext::readbacks`]).
    readbacks: std::sync::Arc<std::sync::atomic::AtomicU64>,
}

/// Optional features requested when the adapter has them: timestamp queries, for
/// benchmarks (in compute passes) and the viewer's stage times (between passes, inside an
/// encoder). Check `device.features()` before using them.
const OPTIONAL_FEATURES: wgpu::Features =
    wgpu::Features::TIMESTAMP_QUERY.union(wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS);

impl GpuContext {
    /// Creates a headless context, blocking until the device is ready.
    ///
    /// Backends come from `WGPU_BACKEND` (all compiled-in ones when unset). With
    /// `WGPU_ADAPTER_NAME` set, the first adapter whose name contains it (case-insensitive)
    /// is used; otherwise wgpu picks one with `WGPU_POWER_PREF`, high performance by default.
    /// The device gets the adapter's full limits, so storage textures, large buffers and
    /// so on work wherever the hardware allows.
    pub fn new() -> Result<Self, GpuError> {
        pollster::block_on(Self::new_async())
    }

    /// The async form of [`GpuContext::new`].
    pub async fn new_async() -> Result<Self, GpuError> {
        let desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        let backends = desc.backends;
        Self::with_instance(wgpu::Instance::new(desc), backends, None).await
    }

    /// A context on `instance` (created with `backends`) whose adapter can present to
    /// `compatible_surface` when one is given: what a windowed program needs, the surface
    /// being made from the same instance. Adapter choice and device limits as
    /// [`GpuContext::new`].
    pub async fn with_instance(
        instance: wgpu::Instance,
        backends: wgpu::Backends,
        compatible_surface: Option<&wgpu::Surface<'_>>,
    ) -> Result<Self, GpuError> {
        let tried = describe_backends(backends);

        let wanted = std::env::var("WGPU_ADAPTER_NAME")
            .ok()
            .filter(|s| !s.trim().is_empty());
        let adapter = match wanted {
            Some(wanted) => {
                let adapters: Vec<wgpu::Adapter> = instance
                    .enumerate_adapters(backends)
                    .await
                    .into_iter()
                    .filter(|a| compatible_surface.is_none_or(|s| a.is_surface_supported(s)))
                    .collect();
                if adapters.is_empty() {
                    return Err(GpuError::NoAdapter { tried });
                }
                let needle = wanted.trim().to_lowercase();
                match adapters
                    .iter()
                    .find(|a| a.get_info().name.to_lowercase().contains(&needle))
                {
                    Some(a) => a.clone(),
                    None => {
                        let available = adapters
                            .iter()
                            .map(|a| summary_of(&a.get_info()))
                            .collect::<Vec<_>>()
                            .join("; ");
                        return Err(GpuError::AdapterNotFound { wanted, available });
                    }
                }
            }
            None => instance
                .request_adapter(&wgpu::RequestAdapterOptions {
                    power_preference: wgpu::PowerPreference::from_env()
                        .unwrap_or(wgpu::PowerPreference::HighPerformance),
                    force_fallback_adapter: false,
                    compatible_surface,
                    apply_limit_buckets: false,
                })
                .await
                .map_err(|_| GpuError::NoAdapter { tried })?,
        };

        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("scene-core"),
                required_features: adapter.features() & OPTIONAL_FEATURES,
                required_limits: adapter.limits(),
                ..Default::default()
            })
            .await
            .map_err(|e| {
                GpuError::RequestDevice(format!(
                    "{e} (adapter: {})",
                    summary_of(&adapter.get_info())
                ))
            })?;
        Ok(Self {
            instance: Some(instance),
            adapter: Some(adapter),
            device,
            queue,
            readbacks: Default::default(),
        })
    }

    /// A context on a host engine's own device and queue: every method's GPU path then
    /// creates its pipelines, buffers and textures on that device, and records into the
    /// host's encoders. The toolkit needs no feature beyond wgpu's defaults (timestamps are
    /// used where the device has them); its limits are the device's.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue) -> Self {
        Self {
            instance: None,
            adapter: None,
            device,
            queue,
            readbacks: Default::default(),
        }
    }

    /// How many readbacks (buffer or texture copies mapped for the CPU) this context and
    /// its clones have made: every readback of the toolkit goes through the context's
    /// `read_*` helpers, so the difference across a frame is the frame's readbacks. The
    /// frame contract reads nothing back; a harness asserts it with this count.
    pub fn readbacks(&self) -> u64 {
        self.readbacks.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// What the device says of its adapter.
    pub fn adapter_info(&self) -> wgpu::AdapterInfo {
        self.device.adapter_info()
    }

    /// A one-line description of the adapter: name, backend and device type, e.g.
    /// `llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu)`.
    pub fn adapter_summary(&self) -> String {
        summary_of(&self.adapter_info())
    }

    /// Checks a 2D texture size against zero and the device's `max_texture_dimension_2d`.
    pub fn check_texture_size(&self, width: u32, height: u32) -> Result<(), GpuError> {
        let max = self.device.limits().max_texture_dimension_2d;
        let reason = if width == 0 || height == 0 {
            "zero-size textures are not allowed".to_string()
        } else if width > max || height > max {
            format!("the device's max_texture_dimension_2d is {max}")
        } else {
            return Ok(());
        };
        Err(GpuError::InvalidSize {
            width,
            height,
            reason,
        })
    }

    /// Uploads a linear RGB image as an `Rgba32Float` texture (alpha 1) with usages
    /// `TEXTURE_BINDING | STORAGE_BINDING | COPY_SRC | COPY_DST`.
    ///
    /// Errors on a zero or too large size, or a pixel count that does not match it.
    pub fn upload_image(&self, img: &Image) -> Result<wgpu::Texture, GpuError> {
        self.check_texture_size(img.width, img.height)?;
        check_len("image pixels", img.width, img.height, img.pixels.len())?;
        let texture = self.create_texture_2d(
            "image",
            img.width,
            img.height,
            wgpu::TextureFormat::Rgba32Float,
            wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::COPY_SRC
                | wgpu::TextureUsages::COPY_DST,
        );
        let texels: Vec<[f32; 4]> = img
            .pixels
            .iter()
            .map(|p| p.extend(1.0).to_array())
            .collect();
        self.write_texture_2d(&texture, bytemuck::cast_slice(&texels), 16);
        Ok(texture)
    }

    /// Creates a single-mip, single-sample 2D texture (no size checks: see
    /// [`GpuContext::check_texture_size`]).
    pub fn create_texture_2d(
        &self,
        label: &str,
        width: u32,
        height: u32,
        format: wgpu::TextureFormat,
        usage: wgpu::TextureUsages,
    ) -> wgpu::Texture {
        self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    }

    /// A 2D texture of `format` holding `bytes` (tightly packed rows, top row first), with
    /// `usage` plus `COPY_DST`: an engine's texture in a test or an example.
    pub fn texture_with(
        &self,
        label: &str,
        (width, height): (u32, u32),
        format: wgpu::TextureFormat,
        usage: wgpu::TextureUsages,
        bytes: &[u8],
    ) -> wgpu::Texture {
        let texture = self.create_texture_2d(
            label,
            width,
            height,
            format,
            usage | wgpu::TextureUsages::COPY_DST,
        );
        let texel = format.block_copy_size(None).unwrap_or(4);
        self.write_texture_2d(&texture, bytes, texel);
        texture
    }

    /// Writes tightly packed rows into mip 0 of a 2D texture (`Queue::write_texture` needs no
    /// 256-byte row alignment).
    pub fn write_texture_2d(&self, texture: &wgpu::Texture, bytes: &[u8], texel_size: u32) {
        let (width, height) = (texture.width(), texture.height());
        self.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(width * texel_size),
                rows_per_image: Some(height),
            },
            wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
        );
    }

    /// Reads mip 0 (layer 0) of a 2D texture back as tightly packed rows, top row first.
    ///
    /// Handles the 256-byte row alignment of texture-to-buffer copies
    /// (`COPY_BYTES_PER_ROW_ALIGNMENT`) by copying into a padded staging buffer and dropping
    /// the padding. For depth-stencil formats the depth aspect is read. The texture needs
    /// `COPY_SRC` usage.
    pub fn read_texture_bytes(&self, texture: &wgpu::Texture) -> Result<Vec<u8>, GpuError> {
        let format = texture.format();
        let aspect = if format.is_depth_stencil_format() {
            wgpu::TextureAspect::DepthOnly
        } else {
            wgpu::TextureAspect::All
        };
        let texel_size = format
            .block_copy_size(Some(aspect))
            .filter(|_| format.block_dimensions() == (1, 1))
            .ok_or_else(|| {
                GpuError::Readback(format!(
                    "texture format {format:?} cannot be read back texel by texel"
                ))
            })?;
        if !texture.usage().contains(wgpu::TextureUsages::COPY_SRC) {
            return Err(GpuError::Readback(format!(
                "texture lacks COPY_SRC usage (has {:?})",
                texture.usage()
            )));
        }
        let (width, height) = (texture.width(), texture.height());
        let row = width as usize * texel_size as usize;
        let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as usize;
        let padded_row = row.div_ceil(align) * align;
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("texture readback"),
            size: (padded_row * height as usize) as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("texture readback"),
            });
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &staging,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded_row as u32),
                    rows_per_image: Some(height),
                },
            },
            wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
        );
        let padded = self.submit_and_map(encoder, &staging)?;
        if padded_row == row {
            return Ok(padded);
        }
        let mut out = Vec::with_capacity(row * height as usize);
        for r in padded.chunks_exact(padded_row) {
            out.extend_from_slice(&r[..row]);
        }
        Ok(out)
    }

    /// Reads an `Rgba32Float` texture back, one `[r, g, b, a]` per texel, row-major.
    pub fn read_texture_rgba32f(&self, texture: &wgpu::Texture) -> Result<Vec<[f32; 4]>, GpuError> {
        expect_format(texture, "Rgba32Float", |f| {
            f == wgpu::TextureFormat::Rgba32Float
        })?;
        Ok(pod_vec(&self.read_texture_bytes(texture)?))
    }

    /// Reads an `Rgba32Float` texture back as an [`Image`] of its size (alpha dropped): how a
    /// frame target is read for a comparison or a report.
    pub fn read_texture_image(&self, texture: &wgpu::Texture) -> Result<Image, GpuError> {
        let texels = self.read_texture_rgba32f(texture)?;
        Ok(Image {
            width: texture.width(),
            height: texture.height(),
            pixels: texels
                .into_iter()
                .map(|[r, g, b, _]| glam::Vec3::new(r, g, b))
                .collect(),
        })
    }

    /// Reads an `R32Float` (or the depth of a `Depth32Float`) texture back, row-major.
    pub fn read_texture_r32f(&self, texture: &wgpu::Texture) -> Result<Vec<f32>, GpuError> {
        expect_format(texture, "R32Float or Depth32Float", |f| {
            matches!(
                f,
                wgpu::TextureFormat::R32Float | wgpu::TextureFormat::Depth32Float
            )
        })?;
        Ok(pod_vec(&self.read_texture_bytes(texture)?))
    }

    /// Reads an `R32Uint` texture back, row-major.
    pub fn read_texture_r32u(&self, texture: &wgpu::Texture) -> Result<Vec<u32>, GpuError> {
        expect_format(texture, "R32Uint", |f| f == wgpu::TextureFormat::R32Uint)?;
        Ok(pod_vec(&self.read_texture_bytes(texture)?))
    }

    /// Reads a whole buffer back (it needs `COPY_SRC` usage) through a staging buffer.
    pub fn read_buffer(&self, buffer: &wgpu::Buffer) -> Result<Vec<u8>, GpuError> {
        if !buffer.usage().contains(wgpu::BufferUsages::COPY_SRC) {
            return Err(GpuError::Readback(format!(
                "buffer lacks COPY_SRC usage (has {:?})",
                buffer.usage()
            )));
        }
        let size = buffer.size();
        if size == 0 {
            return Ok(Vec::new());
        }
        if !size.is_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT) {
            return Err(GpuError::Readback(format!(
                "buffer size {size} is not a multiple of {}",
                wgpu::COPY_BUFFER_ALIGNMENT
            )));
        }
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("buffer readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("buffer readback"),
            });
        encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, size);
        self.submit_and_map(encoder, &staging)
    }

    /// A zeroed storage buffer of one `vec4<f32>` per pixel of a `width x height` image
    /// (row-major; at least one pixel), readable back (`COPY_SRC`) and clearable or
    /// writable by the queue (`COPY_DST`): the output of the per-pixel passes that write
    /// buffers rather than textures (relighting's display, the IBRR's reconstruction, the
    /// viewer's frames).
    pub fn pixel_buffer(&self, label: &str, width: u32, height: u32) -> wgpu::Buffer {
        let pixels = (width as u64 * height as u64).max(1);
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: pixels * 16,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// The largest storage buffer this device can bind, in bytes: the smaller of its
    /// storage-binding and buffer-size limits. What a method checks its buffers against
    /// before allocating them.
    pub fn storage_binding_limit(&self) -> u64 {
        let limits = self.device.limits();
        limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size)
    }

    /// Checks that `buffer` holds a `vec4<f32>` per pixel of a `width x height` image
    /// (what [`GpuContext::pixel_buffer`] makes); `what` names the buffer in the error.
    pub fn check_pixel_buffer(
        buffer: &wgpu::Buffer,
        width: u32,
        height: u32,
        what: &str,
    ) -> Result<(), GpuError> {
        let needed = width as u64 * height as u64 * 16;
        if buffer.size() < needed {
            return Err(GpuError::InvalidSize {
                width,
                height,
                reason: format!(
                    "the {what} buffer holds {} bytes, {needed} needed",
                    buffer.size()
                ),
            });
        }
        Ok(())
    }

    /// A storage buffer holding `bytes` (16 zero bytes when `bytes` is empty: storage
    /// bindings may not be empty), with `STORAGE` and the `extra` usages.
    pub fn storage_with(
        &self,
        label: &str,
        bytes: &[u8],
        extra: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        self.buffer_with(label, bytes, wgpu::BufferUsages::STORAGE | extra)
    }

    /// A buffer holding `bytes` with `usage` (16 zero bytes when `bytes` is empty: bindings
    /// may not be empty). The toolkit's one way of creating an initialised buffer.
    pub fn buffer_with(
        &self,
        label: &str,
        bytes: &[u8],
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        let bytes: &[u8] = if bytes.is_empty() { &[0u8; 16] } else { bytes };
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage,
            })
    }

    /// A zeroed buffer of at least `bytes` (rounded up to 16) with `usage` plus `COPY_DST`:
    /// where a frame's data is copied in ([`frame::FrameWriter`]) frame after frame.
    pub fn frame_buffer(&self, label: &str, bytes: u64, usage: wgpu::BufferUsages) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes.max(16).next_multiple_of(16),
            usage: usage | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// A uniform buffer holding `value` (a `#[repr(C)]` struct checked against its WGSL
    /// twin with [`crate::check_layout!`]).
    pub fn uniform_buffer<T: Pod>(&self, label: &str, value: &T) -> wgpu::Buffer {
        self.buffer_with(
            label,
            bytemuck::bytes_of(value),
            wgpu::BufferUsages::UNIFORM,
        )
    }

    /// Reads a whole buffer back as elements of `T` (trailing bytes that do not fill a
    /// whole element are dropped).
    pub fn read_buffer_as<T: Pod>(&self, buffer: &wgpu::Buffer) -> Result<Vec<T>, GpuError> {
        Ok(pod_vec(&self.read_buffer(buffer)?))
    }

    /// Submits `encoder` inside a validation error scope, maps `staging` for reading, waits
    /// for the device and returns a copy of the mapped bytes.
    fn submit_and_map(
        &self,
        encoder: wgpu::CommandEncoder,
        staging: &wgpu::Buffer,
    ) -> Result<Vec<u8>, GpuError> {
        self.readbacks
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        self.queue.submit([encoder.finish()]);
        let slice = staging.slice(..);
        let (tx, rx) = mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |result| {
            let _ = tx.send(result);
        });
        let polled = self.device.poll(wgpu::PollType::wait_indefinitely());
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Validation(error.to_string()));
        }
        polled.map_err(|e| GpuError::Readback(format!("device poll failed: {e}")))?;
        match rx.try_recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => return Err(GpuError::Readback(format!("buffer mapping failed: {e}"))),
            Err(_) => {
                return Err(GpuError::Readback(
                    "buffer mapping did not complete after waiting for the device".into(),
                ));
            }
        }
        let bytes = {
            let view = slice
                .get_mapped_range()
                .map_err(|e| GpuError::Readback(format!("mapped range unavailable: {e}")))?;
            view.to_vec()
        };
        staging.unmap();
        Ok(bytes)
    }

    /// Runs `f` inside a validation error scope and turns a captured error into
    /// [`GpuError::Validation`] (blocking; on native backends the scope resolves at once).
    /// Wrap resource and pipeline creation and command submission in it so that a wgpu
    /// validation failure becomes an error value instead of wgpu's default panic.
    pub fn validated<T>(&self, f: impl FnOnce() -> T) -> Result<T, GpuError> {
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let value = f();
        match pollster::block_on(scope.pop()) {
            Some(error) => Err(GpuError::Validation(error.to_string())),
            None => Ok(value),
        }
    }

    /// [`GpuContext::validated`] for work that has its own errors: `f`'s error, or a
    /// captured validation error converted into the caller's error type (a method crate's
    /// error that wraps [`GpuError`]).
    pub fn validated_with<T, E: From<GpuError>>(
        &self,
        f: impl FnOnce() -> Result<T, E>,
    ) -> Result<T, E> {
        self.validated(f)?
    }

    /// Records `f` into a new command encoder and submits it when `f` succeeds (nothing is
    /// submitted when it fails): how a caller runs one frame of a method that records into
    /// an encoder (`GpuFrame::encode`) outside an engine's own frame. Does not wait.
    pub fn submit_encoded<T, E>(
        &self,
        f: impl FnOnce(&mut wgpu::CommandEncoder) -> Result<T, E>,
    ) -> Result<T, E> {
        let mut encoder = self.device.create_command_encoder(&Default::default());
        let value = f(&mut encoder)?;
        self.queue.submit([encoder.finish()]);
        Ok(value)
    }
}

/// Which backends of `requested` this build of wgpu can use, as `vulkan, gl`.
fn describe_backends(requested: wgpu::Backends) -> String {
    let usable = requested & wgpu::Instance::enabled_backend_features();
    let names: Vec<String> = usable
        .iter_names()
        .map(|(name, _)| name.to_lowercase())
        .collect();
    let mut s = if names.is_empty() {
        "none usable in this build".to_string()
    } else {
        names.join(", ")
    };
    if let Ok(env) = std::env::var("WGPU_BACKEND") {
        s.push_str(&format!(" (WGPU_BACKEND={env:?})"));
    }
    s
}

fn summary_of(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type)
}

fn check_len(what: &'static str, width: u32, height: u32, found: usize) -> Result<(), GpuError> {
    let expected = width as usize * height as usize;
    if found == expected {
        Ok(())
    } else {
        Err(GpuError::BadLength {
            what,
            expected,
            found,
        })
    }
}

fn expect_format(
    texture: &wgpu::Texture,
    expected: &'static str,
    ok: impl Fn(wgpu::TextureFormat) -> bool,
) -> Result<(), GpuError> {
    let found = texture.format();
    if ok(found) {
        Ok(())
    } else {
        Err(GpuError::WrongFormat { expected, found })
    }
}

/// Copies bytes into a vector of `T` (the bytes need not be aligned for `T`).
fn pod_vec<T: Pod>(bytes: &[u8]) -> Vec<T> {
    bytes
        .chunks_exact(std::mem::size_of::<T>())
        .map(bytemuck::pod_read_unaligned)
        .collect()
}

/// A G-buffer on the GPU: one texture per [`GBuffer`] channel plus a depth-stencil
/// attachment for rasterisation. All textures are `width x height`, single mip, single
/// sample, row 0 at the top.
///
/// The colour textures have usages `RENDER_ATTACHMENT | TEXTURE_BINDING | STORAGE_BINDING |
/// COPY_SRC | COPY_DST`; `depth_stencil` has `RENDER_ATTACHMENT | TEXTURE_BINDING |
/// COPY_SRC`. Albedo and normal use `Rgba32Float` so that readback is exact.
#[derive(Debug)]
pub struct GpuGBuffer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// [`GpuGBuffer::ALBEDO_FORMAT`]: albedo in `rgb`, radiation mask in `a`.
    pub albedo: wgpu::Texture,
    /// [`GpuGBuffer::NORMAL_FORMAT`]: world normal in `xyz`, `w` unused (0).
    pub normal: wgpu::Texture,
    /// [`GpuGBuffer::DEPTH_FORMAT`]: linear depth / far, 1 on background.
    pub depth: wgpu::Texture,
    /// [`GpuGBuffer::TRIANGLE_ID_FORMAT`]: global triangle id, `u32::MAX` on background.
    pub triangle_id: wgpu::Texture,
    /// [`GpuGBuffer::DEPTH_STENCIL_FORMAT`]: the rasteriser's depth attachment (`None` in a
    /// G-buffer wrapped around an engine's textures, [`GpuGBuffer::from_textures`]).
    pub depth_stencil: Option<wgpu::Texture>,
}

impl GpuGBuffer {
    /// Format of [`GpuGBuffer::albedo`].
    pub const ALBEDO_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
    /// Format of [`GpuGBuffer::normal`].
    pub const NORMAL_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
    /// Format of [`GpuGBuffer::depth`].
    pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;
    /// Format of [`GpuGBuffer::triangle_id`].
    pub const TRIANGLE_ID_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;
    /// Format of [`GpuGBuffer::depth_stencil`].
    pub const DEPTH_STENCIL_FORMAT: wgpu::TextureFormat = raster::DEPTH_FORMAT;
    /// The colour attachment formats in render-target order: albedo, normal, depth,
    /// triangle id.
    pub const COLOR_FORMATS: [wgpu::TextureFormat; 4] = [
        Self::ALBEDO_FORMAT,
        Self::NORMAL_FORMAT,
        Self::DEPTH_FORMAT,
        Self::TRIANGLE_ID_FORMAT,
    ];

    /// Creates the textures (contents undefined until rendered or written; wgpu zeroes
    /// them). Errors on a zero or too large size.
    pub fn new(ctx: &GpuContext, width: u32, height: u32) -> Result<Self, GpuError> {
        ctx.check_texture_size(width, height)?;
        let color = wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::STORAGE_BINDING
            | wgpu::TextureUsages::COPY_SRC
            | wgpu::TextureUsages::COPY_DST;
        let depth_stencil = wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC;
        ctx.validated(|| Self {
            width,
            height,
            albedo: ctx.create_texture_2d(
                "gbuffer albedo",
                width,
                height,
                Self::ALBEDO_FORMAT,
                color,
            ),
            normal: ctx.create_texture_2d(
                "gbuffer normal",
                width,
                height,
                Self::NORMAL_FORMAT,
                color,
            ),
            depth: ctx.create_texture_2d("gbuffer depth", width, height, Self::DEPTH_FORMAT, color),
            triangle_id: ctx.create_texture_2d(
                "gbuffer triangle id",
                width,
                height,
                Self::TRIANGLE_ID_FORMAT,
                color,
            ),
            depth_stencil: Some(ctx.create_texture_2d(
                "gbuffer depth-stencil",
                width,
                height,
                Self::DEPTH_STENCIL_FORMAT,
                depth_stencil,
            )),
        })
    }

    /// Wraps an engine's own G-buffer textures (no copy) after checking them: the same
    /// size, single-sampled 2D, the formats of [`GpuGBuffer::COLOR_FORMATS`] (albedo and
    /// radiation mask `Rgba32Float`, world normal `Rgba32Float`, linear depth divided by the
    /// far plane `R32Float` with 1 on background, triangle id `R32Uint` with `u32::MAX` on
    /// background) and `TEXTURE_BINDING` usage. The result has no depth-stencil attachment.
    ///
    /// Errors name the texture and what is wrong with it.
    pub fn from_textures(
        albedo: wgpu::Texture,
        normal: wgpu::Texture,
        depth: wgpu::Texture,
        triangle_id: wgpu::Texture,
    ) -> Result<Self, GpuError> {
        let (width, height) = (albedo.width(), albedo.height());
        let named = [
            ("albedo", &albedo, Self::ALBEDO_FORMAT, "Rgba32Float"),
            ("normal", &normal, Self::NORMAL_FORMAT, "Rgba32Float"),
            ("depth", &depth, Self::DEPTH_FORMAT, "R32Float"),
            (
                "triangle id",
                &triangle_id,
                Self::TRIANGLE_ID_FORMAT,
                "R32Uint",
            ),
        ];
        for (name, t, format, expected) in named {
            if t.format() != format {
                return Err(GpuError::WrongFormat {
                    expected,
                    found: t.format(),
                });
            }
            if (t.width(), t.height()) != (width, height) {
                return Err(GpuError::InvalidSize {
                    width: t.width(),
                    height: t.height(),
                    reason: format!("the {name} texture must match albedo's {width}x{height}"),
                });
            }
            if t.dimension() != wgpu::TextureDimension::D2
                || t.sample_count() != 1
                || t.depth_or_array_layers() != 1
            {
                return Err(GpuError::Validation(format!(
                    "the {name} texture must be a single-sampled, single-layer 2D texture"
                )));
            }
            if !t.usage().contains(wgpu::TextureUsages::TEXTURE_BINDING) {
                return Err(GpuError::Validation(format!(
                    "the {name} texture needs TEXTURE_BINDING usage (has {:?})",
                    t.usage()
                )));
            }
        }
        Ok(Self {
            width,
            height,
            albedo,
            normal,
            depth,
            triangle_id,
            depth_stencil: None,
        })
    }

    /// The rasteriser's depth attachment, or an error naming what lacks it.
    pub fn depth_attachment(&self) -> Result<&wgpu::Texture, GpuError> {
        self.depth_stencil.as_ref().ok_or_else(|| {
            GpuError::Validation(
                "this G-buffer wraps an engine's textures and has no depth-stencil attachment"
                    .into(),
            )
        })
    }

    /// Creates a GPU G-buffer holding a copy of `gbuffer` (the depth-stencil attachment is
    /// left cleared: depth textures cannot be written by copies).
    pub fn upload(ctx: &GpuContext, gbuffer: &GBuffer) -> Result<Self, GpuError> {
        let gpu = Self::new(ctx, gbuffer.width, gbuffer.height)?;
        gpu.write(ctx, gbuffer)?;
        Ok(gpu)
    }

    /// Overwrites the colour textures with `gbuffer`, which must have the same size.
    pub fn write(&self, ctx: &GpuContext, gbuffer: &GBuffer) -> Result<(), GpuError> {
        if (gbuffer.width, gbuffer.height) != (self.width, self.height) {
            return Err(GpuError::InvalidSize {
                width: gbuffer.width,
                height: gbuffer.height,
                reason: format!("the GPU G-buffer is {}x{}", self.width, self.height),
            });
        }
        let (w, h) = (self.width, self.height);
        check_len("G-buffer albedo", w, h, gbuffer.albedo.len())?;
        check_len("G-buffer normal", w, h, gbuffer.normal.len())?;
        check_len("G-buffer depth", w, h, gbuffer.depth.len())?;
        check_len("G-buffer triangle_id", w, h, gbuffer.triangle_id.len())?;
        let normals: Vec<Vec4> = gbuffer.normal.iter().map(|n| n.extend(0.0)).collect();
        ctx.validated(|| {
            ctx.write_texture_2d(&self.albedo, bytemuck::cast_slice(&gbuffer.albedo), 16);
            ctx.write_texture_2d(&self.normal, bytemuck::cast_slice(&normals), 16);
            ctx.write_texture_2d(&self.depth, bytemuck::cast_slice(&gbuffer.depth), 4);
            ctx.write_texture_2d(
                &self.triangle_id,
                bytemuck::cast_slice(&gbuffer.triangle_id),
                4,
            );
        })
    }

    /// The explicit readback step: copies all colour textures to the CPU.
    pub fn read_back(&self, ctx: &GpuContext) -> Result<GBuffer, GpuError> {
        let albedo = ctx
            .read_texture_rgba32f(&self.albedo)?
            .into_iter()
            .map(Vec4::from_array)
            .collect();
        let normal = ctx
            .read_texture_rgba32f(&self.normal)?
            .into_iter()
            .map(|[x, y, z, _]| Vec3::new(x, y, z))
            .collect();
        Ok(GBuffer {
            width: self.width,
            height: self.height,
            albedo,
            normal,
            depth: ctx.read_texture_r32f(&self.depth)?,
            triangle_id: ctx.read_texture_r32u(&self.triangle_id)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::gpu_test_context;

    /// A small deterministic generator (xorshift), so the tests need no extra crate.
    struct Rng(u64);

    impl Rng {
        fn next_f32(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    #[test]
    fn a_pixel_buffer_too_small_for_its_image_is_a_typed_error() {
        let Some(ctx) = gpu_test_context() else {
            return;
        };
        let b = ctx.pixel_buffer("test", 7, 5);
        assert_eq!(b.size(), 7 * 5 * 16);
        assert!(GpuContext::check_pixel_buffer(&b, 7, 5, "test").is_ok());
        assert!(GpuContext::check_pixel_buffer(&b, 5, 7, "test").is_ok());
        let e = GpuContext::check_pixel_buffer(&b, 8, 5, "display output").unwrap_err();
        assert!(
            e.to_string()
                .contains("the display output buffer holds 560 bytes, 640 needed"),
            "{e}"
        );
        // Never an empty buffer, even for an empty image.
        assert_eq!(ctx.pixel_buffer("empty", 0, 0).size(), 16);
    }

    #[test]
    fn uploading_an_image_of_zero_size_or_a_wrong_length_is_an_error() {
        let Some(ctx) = gpu_test_context() else {
            return;
        };
        eprintln!("GPU tests on {}", ctx.adapter_summary());
        for (w, h) in [(0, 0), (0, 5), (5, 0)] {
            let err = ctx.upload_image(&Image::new(w, h)).unwrap_err();
            assert!(matches!(err, GpuError::InvalidSize { .. }), "{err}");
        }
        let bad = Image {
            width: 2,
            height: 2,
            pixels: vec![Vec3::ONE; 3],
        };
        assert!(matches!(
            ctx.upload_image(&bad),
            Err(GpuError::BadLength { .. })
        ));
    }

    #[test]
    fn gpu_gbuffer_round_trips_exactly() {
        let Some(ctx) = gpu_test_context() else {
            return;
        };
        let (w, h) = (13, 7);
        let mut rng = Rng(12345);
        let mut cpu = GBuffer::background(w, h);
        for i in 0..cpu.len() {
            if i % 5 == 3 {
                continue; // keep some background pixels
            }
            let mut r = || rng.next_f32();
            cpu.albedo[i] = Vec4::new(r(), r(), r(), 1.0);
            cpu.normal[i] = Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5).normalize();
            cpu.depth[i] = r();
            cpu.triangle_id[i] = (r() * 1e6) as u32;
        }
        let gpu = GpuGBuffer::upload(&ctx, &cpu).unwrap();
        assert_eq!((gpu.width, gpu.height), (w, h));
        let back = gpu.read_back(&ctx).unwrap();
        assert_eq!(back, cpu);
        // The depth attachment reads back too (cleared to zero by wgpu).
        let depth = ctx
            .read_texture_r32f(gpu.depth_attachment().unwrap())
            .unwrap();
        assert_eq!(depth.len(), cpu.len());
    }

    #[test]
    fn gpu_gbuffer_rejects_bad_sizes() {
        let Some(ctx) = gpu_test_context() else {
            return;
        };
        assert!(matches!(
            GpuGBuffer::new(&ctx, 0, 4),
            Err(GpuError::InvalidSize { .. })
        ));
        let max = ctx.device.limits().max_texture_dimension_2d;
        assert!(matches!(
            GpuGBuffer::new(&ctx, max + 1, 1),
            Err(GpuError::InvalidSize { .. })
        ));
        let gpu = GpuGBuffer::new(&ctx, 3, 2).unwrap();
        assert!(gpu.write(&ctx, &GBuffer::background(2, 3)).is_err());
        let mut short = GBuffer::background(3, 2);
        short.depth.pop();
        assert!(matches!(
            gpu.write(&ctx, &short),
            Err(GpuError::BadLength { .. })
        ));
    }

    #[test]
    fn gpu_readers_check_format_and_usage() {
        let Some(ctx) = gpu_test_context() else {
            return;
        };
        let tex = ctx.upload_image(&Image::new(3, 3)).unwrap();
        assert!(matches!(
            ctx.read_texture_r32u(&tex),
            Err(GpuError::WrongFormat { .. })
        ));
        let no_copy = ctx.create_texture_2d(
            "no copy",
            2,
            2,
            wgpu::TextureFormat::R32Float,
            wgpu::TextureUsages::TEXTURE_BINDING,
        );
        assert!(matches!(
            ctx.read_texture_r32f(&no_copy),
            Err(GpuError::Readback(_))
        ));
        // Image upload round trip, alpha set to 1.
        let img = Image::filled(5, 3, Vec3::new(0.25, 0.5, 4.0));
        let back = ctx
            .read_texture_rgba32f(&ctx.upload_image(&img).unwrap())
            .unwrap();
        assert!(back.iter().all(|&p| p == [0.25, 0.5, 4.0, 1.0]));
    }

    #[test]
    fn gpu_error_message_names_the_fix() {
        let msg = GpuError::NoAdapter {
            tried: "vulkan, gl".into(),
        }
        .to_string();
        assert!(msg.contains("backends tried: vulkan, gl"), "{msg}");
        assert!(msg.contains("apt-get install mesa-vulkan-drivers"), "{msg}");
        assert!(msg.contains("WGPU_BACKEND/WGPU_ADAPTER_NAME"), "{msg}");
    }
}
