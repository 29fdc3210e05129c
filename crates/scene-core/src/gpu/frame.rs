//! The GPU frame contract every method meets (issue 30, docs/engine.md): [`GpuFrame`], one
//! short trait whose `encode` records a frame into the host's encoder from
//! [`FrameInputs`] (the G-buffer, the view, the frame's light state) into the host's target
//! texture; and what a method's frame uses so that a steady stream of frames creates no GPU
//! object: per-frame data written by commands of the frame's own encoder
//! ([`FrameWriter`]), buffers kept while their data fits ([`KeptBuffer`]), bind groups (and
//! other things made from a frame's inputs) kept while those inputs stay the same
//! ([`Keyed`]), a pass that
//! turns a method's pixel buffer into the target ([`PixelsToTexture`]), and wgpu's
//! live-object counters to check it ([`ObjectCounts`]).
//!
//! Why commands of the frame's encoder rather than `Queue::write_buffer`: a queue write lands
//! before the next submission's first command, so two frames encoded before one submit would
//! both read the second frame's values. A copy recorded in the encoder lands between the
//! passes of the frames, in order.

use std::sync::Mutex;

/// Writes a frame's data (uniforms, light factors, per-pixel inputs) into buffers by copies
/// recorded in the frame's own encoder, staged in a `wgpu::util::StagingBelt` whose chunks
/// return once the encoder's submission has run: after the first frames, no buffer is
/// created. Call [`FrameWriter::finish`] on the encoder after the frame's last write; the
/// encoder must then be submitted (an encoder dropped unsubmitted keeps its chunk, and the
/// next frame stages into a new one).
pub struct FrameWriter {
    belt: Mutex<wgpu::util::StagingBelt>,
}

impl std::fmt::Debug for FrameWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrameWriter").finish_non_exhaustive()
    }
}

impl FrameWriter {
    /// A writer staging in chunks of at least `chunk_bytes` (a larger write gets a chunk of
    /// its own size, reused by later frames of that size).
    pub fn new(device: &wgpu::Device, chunk_bytes: u64) -> Self {
        Self {
            belt: Mutex::new(wgpu::util::StagingBelt::new(
                device.clone(),
                chunk_bytes.max(256),
            )),
        }
    }

    /// Records a copy of `bytes` into `target` at `offset` (multiples of 4; `target` needs
    /// `COPY_DST`). Empty `bytes` record nothing.
    pub fn write(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::Buffer,
        offset: u64,
        bytes: &[u8],
    ) {
        let Some(size) = wgpu::BufferSize::new(bytes.len() as u64) else {
            return;
        };
        let mut belt = self.belt.lock().unwrap_or_else(|e| e.into_inner());
        belt.write_buffer(encoder, target, offset, size)
            .copy_from_slice(bytes);
    }

    /// Closes the frame's staging: its chunks come back when `encoder`'s submission has run.
    pub fn finish(&self, encoder: &wgpu::CommandEncoder) {
        let mut belt = self.belt.lock().unwrap_or_else(|e| e.into_inner());
        belt.finish_and_recall_on_submit(encoder);
    }
}

/// A value made from a frame's inputs, a bind group most often, kept with the key it was
/// made for (the textures and buffers it binds, by identity, and the generations of those
/// the method replaces) and made again only when a frame's key differs: how a steady stream
/// of frames on the same inputs creates no GPU object. The old value is dropped before the
/// new one is made.
#[derive(Debug)]
pub struct Keyed<K, V> {
    kept: Option<(K, V)>,
}

impl<K, V> Default for Keyed<K, V> {
    fn default() -> Self {
        Self { kept: None }
    }
}

impl<K: PartialEq, V> Keyed<K, V> {
    /// Nothing kept.
    pub const fn new() -> Self {
        Self { kept: None }
    }

    /// True when the value kept was made for `key`.
    pub fn is_for(&self, key: &K) -> bool {
        self.kept.as_ref().is_some_and(|(k, _)| k == key)
    }

    /// The value kept, whatever its key.
    pub fn value(&self) -> Option<&V> {
        self.kept.as_ref().map(|(_, v)| v)
    }

    /// The value for `key`: the one kept when it was made for `key`, else `make(&key)`,
    /// kept in its place.
    pub fn get_or_make(&mut self, key: K, make: impl FnOnce(&K) -> V) -> &V {
        match self.get_or_try_make(key, |k| Ok::<V, std::convert::Infallible>(make(k))) {
            Ok(v) => v,
            Err(never) => match never {},
        }
    }

    /// [`Keyed::get_or_make`] for a `make` that can fail; on failure nothing is kept.
    pub fn get_or_try_make<E>(
        &mut self,
        key: K,
        make: impl FnOnce(&K) -> Result<V, E>,
    ) -> Result<&V, E> {
        if !self.is_for(&key) {
            self.kept = None;
            let value = make(&key)?;
            self.kept = Some((key, value));
        }
        Ok(&self.kept.as_ref().expect("kept above").1)
    }

    /// Keeps `value` for `key` (for a value made where `make` could not borrow its maker).
    pub fn set(&mut self, key: K, value: V) {
        self.kept = Some((key, value));
    }

    /// Drops what is kept.
    pub fn clear(&mut self) {
        self.kept = None;
    }
}

/// A buffer that is kept while what it must hold fits, and replaced (with a new
/// [`KeptBuffer::generation`], so bind groups over it are remade) when it must grow.
#[derive(Debug)]
pub struct KeptBuffer {
    label: &'static str,
    usage: wgpu::BufferUsages,
    buffer: Option<wgpu::Buffer>,
    generation: u64,
}

impl KeptBuffer {
    /// No buffer yet; `usage` gains `COPY_DST`.
    pub fn new(label: &'static str, usage: wgpu::BufferUsages) -> Self {
        Self {
            label,
            usage: usage | wgpu::BufferUsages::COPY_DST,
            buffer: None,
            generation: 0,
        }
    }

    /// The buffer, at least `bytes` long (at least 16: bindings may not be empty); created
    /// or replaced only when the current one is too small.
    pub fn ensure(&mut self, device: &wgpu::Device, bytes: u64) -> &wgpu::Buffer {
        let bytes = bytes.max(16).next_multiple_of(16);
        if self.buffer.as_ref().is_none_or(|b| b.size() < bytes) {
            self.generation += 1;
            self.buffer = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(self.label),
                size: bytes,
                usage: self.usage,
                mapped_at_creation: false,
            }));
        }
        self.buffer.as_ref().expect("created above")
    }

    /// Bumped each time the buffer is replaced.
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// The buffer as it is (`None` before the first [`KeptBuffer::ensure`]).
    pub fn clone_buffer(&self) -> Option<wgpu::Buffer> {
        self.buffer.clone()
    }
}

/// Live GPU objects of a device by kind, from wgpu's internal counters (the `counters`
/// feature, on in this workspace): read just before and just after recording a frame, the
/// difference is what the frame created (nothing is freed in between: wgpu frees objects
/// only when the device is polled after their last use).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ObjectCounts {
    /// Buffers.
    pub buffers: isize,
    /// Textures.
    pub textures: isize,
    /// Texture views.
    pub texture_views: isize,
    /// Bind groups.
    pub bind_groups: isize,
    /// Render and compute pipelines, pipeline layouts, bind group layouts and shader
    /// modules together.
    pub pipelines: isize,
    /// Samplers and query sets.
    pub other: isize,
}

impl ObjectCounts {
    /// The device's live objects now. All zero when wgpu was built without `counters`
    /// ([`ObjectCounts::available`] tells).
    pub fn of(device: &wgpu::Device) -> Self {
        let c = device.get_internal_counters().hal;
        Self {
            buffers: c.buffers.read(),
            textures: c.textures.read(),
            texture_views: c.texture_views.read(),
            bind_groups: c.bind_groups.read(),
            pipelines: c.render_pipelines.read()
                + c.compute_pipelines.read()
                + c.pipeline_layouts.read()
                + c.bind_group_layouts.read()
                + c.shader_modules.read(),
            other: c.samplers.read() + c.query_sets.read(),
        }
    }

    /// True when the counters count (some object exists on any device that ran anything).
    pub fn available(device: &wgpu::Device) -> bool {
        Self::of(device) != Self::default()
    }

    /// Runs `record` (a frame's recording, before its submit) and returns its result with
    /// the objects it created on `device`.
    pub fn during<T>(device: &wgpu::Device, record: impl FnOnce() -> T) -> (T, ObjectCounts) {
        let before = Self::of(device);
        let result = record();
        (result, before.created_since(&Self::of(device)))
    }

    /// What `after` has more than `self`.
    pub fn created_since(&self, after: &ObjectCounts) -> ObjectCounts {
        ObjectCounts {
            buffers: after.buffers - self.buffers,
            textures: after.textures - self.textures,
            texture_views: after.texture_views - self.texture_views,
            bind_groups: after.bind_groups - self.bind_groups,
            pipelines: after.pipelines - self.pipelines,
            other: after.other - self.other,
        }
    }

    /// The line the engine examples end with: `steady-state frame: B buffers, T textures, G
    /// bind groups, P pipelines created` for these counts, or a note that `device`'s wgpu
    /// was built without its `counters` feature.
    pub fn steady_state_line(&self, device: &wgpu::Device) -> String {
        if Self::available(device) {
            format!(
                "steady-state frame: {} buffers, {} textures, {} bind groups, {} pipelines created",
                self.buffers, self.textures, self.bind_groups, self.pipelines
            )
        } else {
            "steady-state frame: wgpu was built without its `counters` feature".into()
        }
    }

    /// True when every count is zero.
    pub fn is_zero(&self) -> bool {
        *self == Self::default()
    }
}

impl std::fmt::Display for ObjectCounts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} buffers, {} textures, {} texture views, {} bind groups, {} pipelines, {} other",
            self.buffers,
            self.textures,
            self.texture_views,
            self.bind_groups,
            self.pipelines,
            self.other
        )
    }
}

/// What one frame of any method reads: the G-buffer of the frame's view (the toolkit's own,
/// or the host's converted by [`super::HostGBufferPass`]), the view (from the host's
/// matrices by [`crate::View::from_host_matrices`]) and the frame's light state.
#[derive(Clone, Copy, Debug)]
pub struct FrameInputs<'a> {
    /// The frame's G-buffer.
    pub gbuffer: &'a super::GpuGBuffer,
    /// The frame's view.
    pub view: &'a crate::View,
    /// The frame's light state (recolour, dim, switch, direct and indirect multipliers).
    pub lights: &'a crate::LightState,
}

/// The one GPU frame contract: a method prepared on the host's device (its constructor, on
/// a [`super::GpuContext`] made with [`super::GpuContext::from_device`]; pipelines are
/// compiled there, never in `encode`) records each frame into the host's encoder.
///
/// The shape is that of wgpu's examples' `render` and of a render-graph node: inputs in, one
/// target out, nothing submitted, nothing read back. Implemented by ISR and DL
/// (`isr::IsrFrame`), relighting (`relight_pr::gpu_frame::RelightFrame`, which renders its own
/// element ids with `relight_pr::element_ids::TriangleIdPass`) and the IBRR (`ibrr_ldc::IbrrFrame`).
pub trait GpuFrame {
    /// The method's short name.
    fn name(&self) -> &str;

    /// Records one frame into `encoder`: reads `inputs`, writes radiance (`rgb`, `a` = 1)
    /// into `target`, an `Rgba32Float` or `Rgba16Float` texture of the G-buffer's size with
    /// `STORAGE_BINDING` usage ([`check_frame_target`]). Once the inputs' textures and the
    /// target have been seen, a frame creates no GPU object.
    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &FrameInputs<'_>,
        target: &wgpu::Texture,
    ) -> Result<(), crate::Error>;
}

/// Checks a frame target: `width x height`, `Rgba32Float` or `Rgba16Float`, with
/// `STORAGE_BINDING` usage; the error names what is wrong.
pub fn check_frame_target(
    target: &wgpu::Texture,
    width: u32,
    height: u32,
) -> Result<(), super::GpuError> {
    let format = target.format();
    if !matches!(
        format,
        wgpu::TextureFormat::Rgba32Float | wgpu::TextureFormat::Rgba16Float
    ) {
        return Err(super::GpuError::WrongFormat {
            found: format,
            expected: "Rgba32Float or Rgba16Float (the frame target)",
        });
    }
    if (target.width(), target.height()) != (width, height) {
        return Err(super::GpuError::InvalidSize {
            width: target.width(),
            height: target.height(),
            reason: format!("the frame target must be the G-buffer's {width}x{height}"),
        });
    }
    if !target
        .usage()
        .contains(wgpu::TextureUsages::STORAGE_BINDING)
    {
        return Err(super::GpuError::Validation(format!(
            "the frame target needs STORAGE_BINDING usage (has {:?})",
            target.usage()
        )));
    }
    Ok(())
}

/// The pass writing a pixel buffer into a frame target (`Rgba32Float`).
pub const PIXELS_TO_TEXTURE: super::shader::ShaderPass = super::shader::ShaderPass::new(
    "scene-core/pixels_to_texture",
    crate::wgsl_file!("scene-core", "pixels_to_texture.wgsl"),
    &[],
);
/// The same writing `Rgba16Float`.
pub const PIXELS_TO_TEXTURE_RGBA16F: super::shader::ShaderPass = PIXELS_TO_TEXTURE.with_defs(
    "scene-core/pixels_to_texture (rgba16f)",
    &["OUTPUT_RGBA16F"],
);

/// Writes a method's pixel buffer (one `vec4<f32>` per pixel, row-major, radiance in
/// `rgb`) into a frame target, alpha 1, in one compute pass of the frame's encoder; its bind
/// group is kept while the buffer and the target stay the same. Both pipelines are compiled
/// in [`PixelsToTexture::new`].
pub struct PixelsToTexture {
    rgba32f: super::compute::ComputePass,
    rgba16f: super::compute::ComputePass,
    /// Bind groups of the last few (buffer, target) pairs, newest last: a method drawing
    /// into two targets in turn (a split view) keeps both.
    bound: Mutex<Vec<((wgpu::Buffer, wgpu::Texture), wgpu::BindGroup)>>,
}

/// How many (buffer, target) bind groups [`PixelsToTexture`] keeps.
const KEPT_TARGETS: usize = 4;

impl std::fmt::Debug for PixelsToTexture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PixelsToTexture").finish_non_exhaustive()
    }
}

impl PixelsToTexture {
    /// Compiles both variants on `ctx`'s device.
    pub fn new(ctx: &super::GpuContext) -> Result<Self, super::GpuError> {
        use super::layout::{storage_buffer, storage_texture};
        let make = |pass: &super::shader::ShaderPass, format| {
            super::compute::ComputePass::new(
                &ctx.device,
                "scene-core pixels to texture",
                pass,
                &[storage_buffer(0), storage_texture(1, format)],
                &[],
            )
        };
        Ok(Self {
            rgba32f: make(&PIXELS_TO_TEXTURE, wgpu::TextureFormat::Rgba32Float)?,
            rgba16f: make(&PIXELS_TO_TEXTURE_RGBA16F, wgpu::TextureFormat::Rgba16Float)?,
            bound: Mutex::new(Vec::new()),
        })
    }

    /// Records the copy of `pixels` into `target` (checked by [`check_frame_target`] against
    /// its own size; `pixels` must hold at least one `vec4<f32>` per texel).
    pub fn encode(
        &self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        pixels: &wgpu::Buffer,
        target: &wgpu::Texture,
    ) -> Result<(), super::GpuError> {
        let (w, h) = (target.width(), target.height());
        check_frame_target(target, w, h)?;
        if pixels.size() < u64::from(w) * u64::from(h) * 16 {
            return Err(super::GpuError::BadLength {
                what: "the pixel buffer (bytes)",
                expected: w as usize * h as usize * 16,
                found: pixels.size() as usize,
            });
        }
        let pass = if target.format() == wgpu::TextureFormat::Rgba16Float {
            &self.rgba16f
        } else {
            &self.rgba32f
        };
        let key = (pixels.clone(), target.clone());
        let mut bound = self.bound.lock().unwrap_or_else(|e| e.into_inner());
        // The pipelines differ by format: a key is a buffer, a target and so a pipeline.
        let bind = match bound.iter().position(|(k, _)| *k == key) {
            Some(i) => bound[i].1.clone(),
            None => {
                let view = target.create_view(&Default::default());
                let bind = pass.bind(
                    device,
                    &[
                        pixels.as_entire_binding(),
                        wgpu::BindingResource::TextureView(&view),
                    ],
                );
                if bound.len() == KEPT_TARGETS {
                    bound.remove(0);
                }
                bound.push((key, bind.clone()));
                bind
            }
        };
        drop(bound);
        pass.dispatch(encoder, &bind, w, h, None);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::Keyed;

    /// A value is made once per key and again only when the key changes; a failed make
    /// keeps nothing, so the next call makes it again.
    #[test]
    fn keyed_makes_again_only_when_the_key_changes() {
        let mut made = 0;
        let mut kept: Keyed<(u32, u64), String> = Keyed::new();
        for key in [(1, 0), (1, 0), (2, 0), (2, 0), (2, 1), (1, 0)] {
            let v = kept.get_or_make(key, |k| {
                made += 1;
                format!("{k:?}")
            });
            assert_eq!(*v, format!("{key:?}"));
        }
        assert_eq!(made, 4, "made for (1, 0), (2, 0), (2, 1) and (1, 0) again");
        let failed = kept.get_or_try_make((3, 0), |_| Err::<String, _>("no"));
        assert_eq!(failed, Err("no"));
        assert!(kept.value().is_none() && !kept.is_for(&(1, 0)));
        assert_eq!(kept.get_or_make((1, 0), |_| "again".into()), "again");
    }
}
