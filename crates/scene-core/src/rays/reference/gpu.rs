//! The reference path tracer on the GPU (features `gpu` and `reference`): the CPU tracer's
//! estimator ([`super::PathTracer`], which stays the definition) as one wgpu compute shader
//! over the same four-wide BVH, in storage buffers. It needs no ray-query hardware, so it
//! runs on every wgpu backend, lavapipe included.
//!
//! What it shares with the CPU tracer and where it differs is written at the top of
//! `shaders/scene-core/path_tracer.wgsl`. In short: the same lights, alpha masks,
//! textures, bounce limits, Russian roulette, MIS and stratified first vertices; other
//! random numbers, so the two agree in distribution, not bit for bit (`tests/gpu_reference.rs`
//! compares them block by block). A seed gives the same image on one adapter whatever the
//! split into passes.
//!
//! ```no_run
//! use scene_core::{builtin, gpu::GpuContext, reference::{Bounces, GpuPathTracer}, LightState, View};
//!
//! let ctx = GpuContext::new().unwrap();
//! let scene = builtin::scene("cornell").unwrap();
//! let view = View::from_camera(&scene.cameras[0]);
//! let tracer = GpuPathTracer::new(&ctx, &scene, &LightState::default()).unwrap();
//! let mut acc = tracer.accumulator(128, 128).unwrap();
//! tracer.add_pass(&mut acc, &view, Bounces::Unlimited, 1, 64, None).unwrap();
//! let image = acc.image().unwrap();
//! ```

use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use glam::{Vec2, Vec3};

use crate::BudgetExceeded;
use crate::gpu::frame::{FrameInputs, FrameWriter, GpuFrame, KeptBuffer, Keyed, PixelsToTexture};
use crate::gpu::shader::ShaderPass;
use crate::gpu::{ComputePass, GpuContext, GpuError, WORKGROUP};
use crate::image::Image;
use crate::lights::{Emitters, LightId, LightState, SpotRamp};
use crate::ray::{Hit, RayQuery, RayScene};
use crate::scene::Scene;
use crate::view::{Projection, View};

use super::{Bounces, ReferenceSettings};

/// The GPU path tracer's shader (`shaders/scene-core/path_tracer.wgsl`).
pub const PATH_TRACER: ShaderPass = ShaderPass::new(
    "scene-core/path_tracer",
    crate::wgsl_file!("scene-core", "path_tracer.wgsl"),
    &[crate::gpu::shader::TEXTURE_WRAP],
);

/// Paths one dispatch traces at most (at least one sample of every pixel): short enough
/// that progress is reported often and no driver watchdog fires.
const PATHS_PER_DISPATCH: u64 = 1 << 18;

/// One-sample dispatches one submission records at most (each with its own parameters,
/// copied in by the submission's encoder between the dispatches), and the most samples a
/// [`PathTracerFrame`] adds per frame.
///
/// Every dispatch traces **one sample per pixel**: an invocation never loops over samples.
/// On lavapipe, several samples in one invocation's loop came out wrong, the more so the
/// longer the loop ran: 256 to 1 024 samples gave the corridor a per-sample variance 2-8x
/// too small and a mean 0.5 % off, and even 16 samples of long paths made the Breakfast
/// Room's corner block 5-7 % bright under its sun (6 of 48 blocks rejected by the z-test
/// against the CPU tracer; with one sample per invocation -0.2 % and none rejected, every
/// ray query and every hit's shading data agreeing with the CPU's). The cause inside the
/// driver is not found; one sample per invocation avoids it on every backend, at the price
/// of more dispatches for small images (large ones trace a sample per dispatch anyway).
const SAMPLES_PER_SUBMIT: u32 = 16;

use std::sync::Arc;

/// `Params` of the shader.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct Params {
    cam_o0: [f32; 4],
    cam_ou: [f32; 4],
    cam_ov: [f32; 4],
    cam_d0: [f32; 4],
    cam_du: [f32; 4],
    cam_dv: [f32; 4],
    sky_direct: [f32; 4],
    sky_indirect: [f32; 4],
    width: u32,
    height: u32,
    first_sample: u32,
    samples: u32,
    max_vertex: u32,
    seed_lo: u32,
    seed_hi: u32,
    flags: u32,
    scale: f32,
    eps: f32,
    far: f32,
    n_points: u32,
    n_dirs: u32,
    n_emitters: u32,
    sky_w: u32,
    sky_h: u32,
    off_materials: u32,
    off_textures: u32,
    off_points: u32,
    off_dirs: u32,
    off_emitters: u32,
    off_patterns: u32,
    off_meshes: u32,
    off_sky: u32,
}

const FLAG_SEES_EMISSION: u32 = 1;
const FLAG_SKY: u32 = 2;
const FLAG_SKY_NEE: u32 = 4;
const FLAG_CUTOUTS: u32 = 8;
const FLAG_HITS_ONLY: u32 = 16;
const NONE: u32 = u32::MAX;

/// `bit` where `on`, else no bit.
fn flag(on: bool, bit: u32) -> u32 {
    if on { bit } else { 0 }
}

/// The shader's last reflecting vertex for a bounce limit.
fn max_vertex(bounces: Bounces) -> u32 {
    match bounces {
        Bounces::Limited(n) => n,
        Bounces::Unlimited => u32::MAX - 1,
    }
}

fn v4(v: Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

fn bits(x: u32) -> f32 {
    f32::from_bits(x)
}

/// Walker's alias table over `weights` (Vose's construction, in f64): per entry the
/// threshold below which a uniform number keeps the entry, and the entry taken otherwise.
/// Entry `i` is then drawn with probability `weights[i] / sum` (up to the f32 rounding
/// of the thresholds); all-zero weights give an empty table.
fn alias_table(weights: &[f64]) -> Vec<(f32, u32)> {
    let n = weights.len();
    let total: f64 = weights.iter().sum();
    if n == 0 || !(total > 0.0 && total.is_finite()) {
        return Vec::new();
    }
    let mut scaled: Vec<f64> = weights.iter().map(|w| w / total * n as f64).collect();
    let mut table: Vec<(f32, u32)> = (0..n as u32).map(|i| (1.0, i)).collect();
    let (mut small, mut large): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| scaled[i] < 1.0);
    while let (Some(s), Some(&l)) = (small.pop(), large.last()) {
        table[s] = (scaled[s] as f32, l as u32);
        scaled[l] -= 1.0 - scaled[s];
        if scaled[l] < 1.0 {
            large.pop();
            small.push(l);
        }
    }
    // What is left holds (up to rounding) exactly one entry's worth each.
    table
}

/// A scene prepared for GPU path tracing: the BVH, shading data, lights and textures in
/// storage buffers, and the compiled pipeline. Build one per scene and light state; it
/// traces any view at any size ([`GpuPathTracer::add_pass`]).
pub struct GpuPathTracer {
    ctx: GpuContext,
    pass: ComputePass,
    nodes: wgpu::Buffer,
    packets: wgpu::Buffer,
    tris: wgpu::Buffer,
    data: wgpu::Buffer,
    texels: wgpu::Buffer,
    /// Everything of `Params` but the view, the size and the samples.
    base: Params,
    /// What of `Params` the light state does not change (the scene's flags and sizes).
    fixed: Params,
    /// A camera ray's origin further than this (in the tree's scaled units) is refused.
    far_origin: f32,
    /// The ray-query pipeline ([`GpuPathTracer::trace_rays`]), compiled on first use.
    rays_pass: std::sync::OnceLock<ComputePass>,
}

impl std::fmt::Debug for GpuPathTracer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuPathTracer").finish_non_exhaustive()
    }
}

/// The running mean and variance of a GPU reference image ([`GpuPathTracer::add_pass`]).
#[derive(Debug)]
pub struct GpuAccumulator {
    width: u32,
    height: u32,
    spp: u32,
    accum: wgpu::Buffer,
    params: wgpu::Buffer,
    /// Copies each dispatch's parameters in, between the dispatches of a submission.
    writer: FrameWriter,
    bind: wgpu::BindGroup,
    ctx: GpuContext,
    seconds: f64,
}

impl GpuAccumulator {
    /// Samples per pixel so far.
    pub fn spp(&self) -> u32 {
        self.spp
    }

    /// GPU wall-clock seconds of the passes so far (each pass waits for its work).
    pub fn seconds(&self) -> f64 {
        self.seconds
    }

    /// Reads the mean and the unbiased per-sample variance back.
    fn read(&self) -> Result<(Image, Image), GpuError> {
        let values: Vec<[f32; 4]> = self.ctx.read_buffer_as(&self.accum)?;
        let pixels = self.width as usize * self.height as usize;
        let n = self.spp as f32;
        let rgb = |v: &[f32; 4]| Vec3::new(v[0], v[1], v[2]);
        let mean = values[..pixels].iter().map(rgb).collect();
        let var = values[pixels..2 * pixels]
            .iter()
            .map(|m2| {
                if self.spp < 2 {
                    Vec3::ZERO
                } else {
                    (rgb(m2) / (n - 1.0)).max(Vec3::ZERO)
                }
            })
            .collect();
        let image = |pixels| Image {
            width: self.width,
            height: self.height,
            pixels,
        };
        Ok((image(mean), image(var)))
    }

    /// The mean image (read back from the GPU).
    pub fn image(&self) -> Result<Image, GpuError> {
        Ok(self.read()?.0)
    }

    /// The per-pixel, per-channel sample variance of one sample (unbiased; zero with fewer
    /// than two samples), as [`super::Accumulator::variance`].
    pub fn variance(&self) -> Result<Image, GpuError> {
        Ok(self.read()?.1)
    }
}

/// The result of [`render_gpu`].
#[derive(Clone, Debug)]
pub struct GpuReferenceOutput {
    /// The mean radiance per pixel.
    pub image: Image,
    /// Per-pixel, per-channel sample variance of one sample (see
    /// [`super::ReferenceOutput::variance`]).
    pub variance: Image,
    /// Samples per pixel.
    pub spp: u32,
    /// Seconds the passes took (upload and pipeline creation excluded).
    pub seconds: f64,
    /// Seconds to upload the scene and compile the pipeline.
    pub prepare_seconds: f64,
}

impl GpuReferenceOutput {
    /// Paths traced per second.
    pub fn samples_per_second(&self) -> f64 {
        let paths = self.image.pixels.len() as f64 * f64::from(self.spp);
        if self.seconds > 0.0 {
            paths / self.seconds
        } else {
            0.0
        }
    }
}

impl GpuPathTracer {
    /// Uploads `scene` (validated) under the light state `lights` (as
    /// [`super::PathTracer::with_lights`]). Refuses, before allocating on the GPU, a tree
    /// deeper than the shader's stack and data over the device's storage-binding limit
    /// ([`GpuError::Budget`], naming the buffer).
    pub fn new(ctx: &GpuContext, scene: &Scene, lights: &LightState) -> Result<Self, GpuError> {
        let rays = RayScene::build(scene);
        let extent = scene.extent();
        let ((nodes, packets, deep), scale) = match rays.gpu_tree() {
            Some(t) => t,
            None => ((vec![[0u32; 32]], Vec::new(), false), 1.0),
        };
        let limit = ctx.storage_binding_limit();
        let too_big = |what: &str, bytes: u64| -> Result<(), GpuError> {
            if bytes > limit {
                return Err(GpuError::Budget(BudgetExceeded {
                    what: format!("the GPU path tracer's {what}"),
                    needed: bytes,
                    limit,
                    unit: "bytes",
                    hint: "the device's max_storage_buffer_binding_size; trace this scene \
                           with the CPU reference"
                        .into(),
                }));
            }
            Ok(())
        };
        if deep {
            return Err(GpuError::Budget(BudgetExceeded {
                what: "the GPU path tracer's traversal stack".into(),
                needed: 65,
                limit: 64,
                unit: "entries",
                hint: "the scene's BVH is deeper than the shader's stack; trace it with the \
                       CPU reference"
                    .into(),
            }));
        }
        let triangles = scene.triangle_count() as u64;
        too_big("BVH nodes", nodes.len() as u64 * 128)?;
        too_big("triangle packets", packets.len() as u64 * 160)?;
        too_big("triangle data", triangles * 144)?;
        let texel_count: u64 = scene
            .textures
            .iter()
            .map(|t| t.width as u64 * t.height as u64)
            .sum();
        too_big("texels", texel_count * 16)?;

        // The emitter entry of each triangle does not depend on the light state.
        let emitters = Emitters::new(scene, lights);

        // Per triangle: normals, material, mesh, emitter entry, coordinates, colours.
        let mut tris: Vec<[[f32; 4]; 9]> = Vec::with_capacity(triangles as usize);
        for (mi, mesh) in scene.meshes.iter().enumerate() {
            for (t, &m) in mesh.indices.iter().zip(&mesh.material_ids) {
                let global = tris.len();
                let p = t.map(|i| mesh.positions[i as usize]);
                let ng = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
                let n = t.map(|i| mesh.normals.get(i as usize).copied().unwrap_or(Vec3::ZERO));
                let uv = mesh.uvs.as_ref().map(|uv| t.map(|i| uv[i as usize]));
                let color = mesh.colors.as_ref().map(|c| t.map(|i| c[i as usize]));
                let flags = u32::from(uv.is_some()) | (u32::from(color.is_some()) << 1);
                let uv = uv.unwrap_or([Vec2::ZERO; 3]);
                let color = color.unwrap_or([Vec3::ONE; 3]);
                let emitter = emitters.per_triangle.get(global).copied().unwrap_or(NONE);
                tris.push([
                    v4(ng, bits(m)),
                    v4(n[0], bits(mi as u32)),
                    v4(n[1], bits(emitter)),
                    v4(n[2], bits(flags)),
                    [uv[0].x, uv[0].y, uv[1].x, uv[1].y],
                    [uv[2].x, uv[2].y, 0.0, 0.0],
                    v4(color[0], 0.0),
                    v4(color[1], 0.0),
                    v4(color[2], 0.0),
                ]);
            }
        }

        let sees_emission = scene.meshes.iter().any(|m| {
            m.material_ids.iter().any(|&id| {
                scene
                    .materials
                    .get(id as usize)
                    .is_some_and(|m| m.is_emissive())
            })
        });
        let fixed = Params {
            flags: flag(sees_emission, FLAG_SEES_EMISSION)
                | flag(!rays.cutouts().is_empty(), FLAG_CUTOUTS),
            scale,
            eps: extent * 2e-5,
            far: extent * 4.0,
            ..Zeroable::zeroed()
        };
        let (mut data, base) = pack_lights(scene, lights, &fixed);
        too_big("light and material data", data.len() as u64 * 16)?;
        let mut texels: Vec<[f32; 4]> = Vec::with_capacity(texel_count as usize);
        for t in &scene.textures {
            let n = t.width as usize * t.height as usize;
            let alpha = |i: usize| t.alpha.as_ref().and_then(|a| a.get(i)).copied();
            texels.extend(
                t.texels
                    .iter()
                    .take(n)
                    .enumerate()
                    .map(|(i, c)| v4(*c, alpha(i).unwrap_or(1.0))),
            );
        }

        let entries = layout_entries();
        let pass = ctx.validated(|| {
            ComputePass::new(&ctx.device, "path tracer", &PATH_TRACER, &entries, &[])
        })??;
        // A binding holds at least one element of its type (none is read where there is
        // nothing: the empty tree's root has no children).
        let (mut packets, mut tris, mut texels) = (packets, tris, texels);
        if packets.is_empty() {
            packets.push([0; 40]);
        }
        if tris.is_empty() {
            tris.push(Zeroable::zeroed());
        }
        if data.is_empty() {
            data.push([0.0; 4]);
        }
        if texels.is_empty() {
            texels.push([0.0; 4]);
        }
        let none = wgpu::BufferUsages::empty();
        let (nodes, packets, tris, data, texels) = ctx.validated(|| {
            (
                ctx.storage_with("path tracer nodes", bytemuck::cast_slice(&nodes), none),
                ctx.storage_with("path tracer packets", bytemuck::cast_slice(&packets), none),
                ctx.storage_with("path tracer triangles", bytemuck::cast_slice(&tris), none),
                ctx.storage_with("path tracer data", bytemuck::cast_slice(&data), none),
                ctx.storage_with("path tracer texels", bytemuck::cast_slice(&texels), none),
            )
        })?;
        Ok(Self {
            ctx: ctx.clone(),
            pass,
            nodes,
            packets,
            tris,
            data,
            texels,
            base,
            fixed,
            far_origin: 1e18,
            rays_pass: std::sync::OnceLock::new(),
        })
    }

    /// An empty accumulator for `width x height` pixels. Refuses a zero size and a pixel
    /// buffer over the device's limits.
    pub fn accumulator(&self, width: u32, height: u32) -> Result<GpuAccumulator, GpuError> {
        let bytes = width as u64 * height as u64 * 32;
        if width == 0 || height == 0 || bytes > self.ctx.storage_binding_limit() {
            return Err(GpuError::InvalidSize {
                width,
                height,
                reason: format!(
                    "the GPU path tracer needs a positive size whose 32 bytes a pixel fit the \
                     device's storage-binding limit of {} bytes",
                    self.ctx.storage_binding_limit()
                ),
            });
        }
        let (accum, params) = self.ctx.validated(|| {
            (
                self.ctx.frame_buffer(
                    "path tracer accumulation",
                    bytes,
                    wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                ),
                self.ctx.frame_buffer(
                    "path tracer params",
                    size_of::<Params>() as u64,
                    wgpu::BufferUsages::UNIFORM,
                ),
            )
        })?;
        let bind = self
            .ctx
            .validated(|| self.bind(&params, &self.data, &accum))?;
        Ok(GpuAccumulator {
            width,
            height,
            spp: 0,
            accum,
            params,
            writer: FrameWriter::new(&self.ctx.device, 1 << 12),
            bind,
            ctx: self.ctx.clone(),
            seconds: 0.0,
        })
    }

    /// Adds `samples` samples per pixel of `view` to `acc`, with bounce limit `bounces`
    /// and `seed` (the same seed for every pass of one image), and waits for them.
    /// `progress(samples_done, samples)` is called after each dispatch. The image after
    /// any sequence of passes is the same as after one pass of their total.
    pub fn add_pass(
        &self,
        acc: &mut GpuAccumulator,
        view: &View,
        bounces: Bounces,
        seed: u64,
        samples: u32,
        progress: Option<&dyn Fn(u32, u32)>,
    ) -> Result<(), GpuError> {
        let camera = self.camera_params(view, &self.base)?;
        let start = Instant::now();
        let samples = samples.min(u32::MAX - acc.spp);
        let pixels = u64::from(acc.width) * u64::from(acc.height);
        let per_submit =
            (PATHS_PER_DISPATCH / pixels).clamp(1, u64::from(SAMPLES_PER_SUBMIT)) as u32;
        let mut done = 0;
        while done < samples {
            let n = per_submit.min(samples - done);
            self.ctx.validated(|| {
                self.ctx.submit_encoded(|encoder| {
                    for j in 0..n {
                        let params = Params {
                            width: acc.width,
                            height: acc.height,
                            first_sample: acc.spp + done + j,
                            samples: 1,
                            max_vertex: max_vertex(bounces),
                            seed_lo: seed as u32,
                            seed_hi: (seed >> 32) as u32,
                            ..camera
                        };
                        acc.writer
                            .write(encoder, &acc.params, 0, bytemuck::bytes_of(&params));
                        let mut cp = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                            label: Some("path tracer"),
                            timestamp_writes: None,
                        });
                        cp.set_pipeline(&self.pass.pipeline);
                        cp.set_bind_group(0, &acc.bind, &[]);
                        cp.dispatch_workgroups(
                            acc.width.div_ceil(WORKGROUP),
                            acc.height.div_ceil(WORKGROUP),
                            1,
                        );
                    }
                    acc.writer.finish(encoder);
                    Ok::<(), GpuError>(())
                })
            })??;
            self.ctx
                .device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| GpuError::Readback(e.to_string()))?;
            done += n;
            if let Some(p) = progress {
                p(done, samples);
            }
        }
        acc.spp += samples;
        acc.seconds += start.elapsed().as_secs_f64();
        Ok(())
    }

    /// The closest hit (alpha masks applied) and the occlusion of each ray, answered by the
    /// shader's traversal of the tree on the GPU, with what the shader's shading reads at
    /// the hit: the ray queries of [`crate::ray::RayScene`] on the device, for checking the
    /// GPU's tree and shading data against the CPU's ray by ray. Directions must be unit
    /// vectors (`t` is a world distance). Waits for the answer (a readback).
    pub fn trace_rays(&self, rays: &[RayQuery]) -> Result<Vec<GpuRayAnswer>, GpuError> {
        self.answer_rays(rays, 0)
    }

    /// The closest hit of each ray (alpha masks applied), found by the GPU's traversal of
    /// the tree: [`crate::ray::RayScene::closest_hits`] on the device, for work that traces
    /// many rays and reads their hits back (the light-space senders' visibility maps of
    /// `isr`). Directions must be unit vectors (`t` is a world distance). Rays go in
    /// batches that fit the device's storage-binding limit; each batch waits for its answer
    /// (a readback).
    pub fn closest_hits(&self, rays: &[RayQuery]) -> Result<Vec<Option<Hit>>, GpuError> {
        // 64 bytes a ray, at most a quarter of the binding limit a batch.
        let batch = ((self.ctx.storage_binding_limit() / 4 / 64).clamp(1, 1 << 22)) as usize;
        let mut out = Vec::with_capacity(rays.len());
        for chunk in rays.chunks(batch) {
            out.extend(
                self.answer_rays(chunk, FLAG_HITS_ONLY)?
                    .into_iter()
                    .map(|a| a.hit),
            );
        }
        Ok(out)
    }

    /// [`GpuPathTracer::trace_rays`] with `flags` added to the shader's (`FLAG_HITS_ONLY`:
    /// no occlusion query and no shading, `occluded` then says whether a hit was found and
    /// the albedo and normal are zero).
    fn answer_rays(&self, rays: &[RayQuery], flags: u32) -> Result<Vec<GpuRayAnswer>, GpuError> {
        if rays.is_empty() {
            return Ok(Vec::new());
        }
        let bytes = rays.len() as u64 * 64;
        if rays.len() > u32::MAX as usize || bytes > self.ctx.storage_binding_limit() {
            return Err(GpuError::Budget(BudgetExceeded {
                what: "the rays of one trace_rays call".into(),
                needed: bytes,
                limit: self.ctx.storage_binding_limit(),
                unit: "bytes",
                hint: "trace them in batches".into(),
            }));
        }
        let input: Vec<[f32; 4]> = rays
            .iter()
            .flat_map(|r| {
                [
                    v4(r.origin, r.t_min),
                    v4(r.direction, r.t_max),
                    [0.0; 4],
                    [0.0; 4],
                ]
            })
            .collect();
        let device = &self.ctx.device;
        let pass = match self.rays_pass.get() {
            Some(pass) => pass,
            None => {
                let module = PATH_TRACER.create_module(device)?;
                let pass = self.ctx.validated(|| {
                    ComputePass::from_entry_point(
                        device,
                        "path tracer rays",
                        &module,
                        "trace_rays",
                        &layout_entries(),
                        &[],
                    )
                })?;
                // Another thread may have set it first: the same pipeline either way.
                self.rays_pass.get_or_init(|| pass)
            }
        };
        let (accum, params) = self.ctx.validated(|| {
            (
                self.ctx.buffer_with(
                    "path tracer rays",
                    bytemuck::cast_slice(&input),
                    wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                ),
                self.ctx.uniform_buffer(
                    "path tracer rays params",
                    &Params {
                        width: rays.len() as u32,
                        flags: self.base.flags | flags,
                        ..self.base
                    },
                ),
            )
        })?;
        let bind = self.ctx.validated(|| {
            pass.bind(
                device,
                &[
                    params.as_entire_binding(),
                    self.nodes.as_entire_binding(),
                    self.packets.as_entire_binding(),
                    self.tris.as_entire_binding(),
                    self.data.as_entire_binding(),
                    self.texels.as_entire_binding(),
                    accum.as_entire_binding(),
                ],
            )
        })?;
        self.ctx.validated(|| {
            self.ctx.submit_encoded(|encoder| {
                let mut cp = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("path tracer rays"),
                    timestamp_writes: None,
                });
                cp.set_pipeline(&pass.pipeline);
                cp.set_bind_group(0, &bind, &[]);
                cp.dispatch_workgroups((rays.len() as u32).div_ceil(64), 1, 1);
                Ok::<(), GpuError>(())
            })
        })??;
        let out: Vec<[f32; 4]> = self.ctx.read_buffer_as(&accum)?;
        let xyz = |v: [f32; 4]| Vec3::new(v[0], v[1], v[2]);
        Ok(out
            .chunks_exact(4)
            .map(|w| GpuRayAnswer {
                hit: (w[0][0] > 0.5).then(|| Hit {
                    triangle: w[0][1].to_bits(),
                    t: w[0][2],
                    barycentric: Vec2::new(w[1][0], w[1][1]),
                }),
                occluded: w[0][3] > 0.5,
                albedo: xyz(w[2]),
                shading_normal: xyz(w[3]),
            })
            .collect())
    }

    /// The pipeline.
    fn pipeline(&self) -> &wgpu::ComputePipeline {
        &self.pass.pipeline
    }

    /// A bind group of the scene's buffers with `params`, `data` and `accum`.
    fn bind(
        &self,
        params: &wgpu::Buffer,
        data: &wgpu::Buffer,
        accum: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        self.pass.bind(
            &self.ctx.device,
            &[
                params.as_entire_binding(),
                self.nodes.as_entire_binding(),
                self.packets.as_entire_binding(),
                self.tris.as_entire_binding(),
                data.as_entire_binding(),
                self.texels.as_entire_binding(),
                accum.as_entire_binding(),
            ],
        )
    }

    /// `base` (the light state's constants) with `view`'s camera rays: origin
    /// `o0 + ou u + ov v`, direction `d0 + du u + dv v` (normalised in the shader), as
    /// [`View::ray`].
    fn camera_params(&self, view: &View, base: &Params) -> Result<Params, GpuError> {
        let (o0, ou, ov, d0, du, dv) = match view.projection {
            Projection::Perspective {
                left,
                right,
                bottom,
                top,
            } => (
                view.eye,
                Vec3::ZERO,
                Vec3::ZERO,
                view.right() * left + view.up * top + view.forward,
                view.right() * (right - left),
                view.up * (bottom - top),
            ),
            Projection::Orthographic { .. } => {
                let at = |u: f32, v: f32| view.reconstruct_world(Vec2::new(u, v), 0.0);
                let o0 = at(0.0, 0.0);
                (
                    o0,
                    at(1.0, 0.0) - o0,
                    at(0.0, 1.0) - o0,
                    view.forward,
                    Vec3::ZERO,
                    Vec3::ZERO,
                )
            }
        };
        let corners = [o0, o0 + ou, o0 + ov, o0 + ou + ov];
        let finite = [o0, ou, ov, d0, du, dv].iter().all(|v| v.is_finite());
        if !finite
            || corners
                .iter()
                .any(|c| (*c * self.base.scale).abs().max_element() > self.far_origin)
        {
            return Err(GpuError::InvalidSize {
                width: 0,
                height: 0,
                reason: format!(
                    "the view's rays start at {o0} (or are not finite): too far from the \
                     scene for the GPU path tracer's f32 ray tests; trace it with the CPU \
                     reference"
                ),
            });
        }
        Ok(Params {
            cam_o0: v4(o0, 0.0),
            cam_ou: v4(ou, 0.0),
            cam_ov: v4(ov, 0.0),
            cam_d0: v4(d0, 0.0),
            cam_du: v4(du, 0.0),
            cam_dv: v4(dv, 0.0),
            ..*base
        })
    }
}

/// One ray's answer from [`GpuPathTracer::trace_rays`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuRayAnswer {
    /// The closest hit that exists.
    pub hit: Option<Hit>,
    /// Whether anything that exists lies on the segment.
    pub occluded: bool,
    /// The albedo the shader reflects with at the hit (material, texture, vertex colours;
    /// zero without a hit).
    pub albedo: Vec3,
    /// The unit shading normal at the hit, on the side of the geometric normal that faces
    /// the ray (zero without a hit).
    pub shading_normal: Vec3,
}

/// The shader's bindings: the uniform `Params`, the scene's five read-only buffers and the
/// read-write accumulation.
fn layout_entries() -> Vec<wgpu::BindGroupLayoutEntry> {
    (0..7)
        .map(|binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: match binding {
                    0 => wgpu::BufferBindingType::Uniform,
                    6 => wgpu::BufferBindingType::Storage { read_only: false },
                    _ => wgpu::BufferBindingType::Storage { read_only: true },
                },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        })
        .collect()
}

/// Renders `scene` from `view` with `settings` under `lights` on the GPU, in one call
/// ([`GpuPathTracer`], [`GpuPathTracer::add_pass`]). `progress(samples_done, samples)`
/// reports progress.
pub fn render_gpu(
    ctx: &GpuContext,
    scene: &Scene,
    view: &View,
    settings: &ReferenceSettings,
    lights: &LightState,
    progress: Option<&dyn Fn(u32, u32)>,
) -> Result<GpuReferenceOutput, GpuError> {
    let start = Instant::now();
    let tracer = GpuPathTracer::new(ctx, scene, lights)?;
    let mut acc = tracer.accumulator(settings.width, settings.height)?;
    let prepare_seconds = start.elapsed().as_secs_f64();
    tracer.add_pass(
        &mut acc,
        view,
        settings.bounces,
        settings.seed,
        settings.spp,
        progress,
    )?;
    let (image, variance) = acc.read()?;
    Ok(GpuReferenceOutput {
        image,
        variance,
        spp: acc.spp,
        seconds: acc.seconds,
        prepare_seconds,
    })
}

/// The sections of the shader's `data` under the light state `lights` (materials, texture
/// infos, lights with their factors, emitters with their alias table and patterns, mesh
/// factors, the sky), and `fixed` (the scene's own flags and sizes) completed with their
/// offsets, counts and the sky's factors.
fn pack_lights(scene: &Scene, lights: &LightState, fixed: &Params) -> (Vec<[f32; 4]>, Params) {
    let emitters = Emitters::new(scene, lights);
    let factors = |id: LightId| {
        let s = lights.get(id);
        [s.direct_factor(), s.indirect_factor()]
    };
    let mut data: Vec<[f32; 4]> = Vec::new();
    let texture = |t: Option<u32>| t.filter(|&t| (t as usize) < scene.textures.len());
    let off_materials = data.len() as u32;
    for m in &scene.materials {
        data.push(v4(
            m.albedo,
            bits(texture(m.albedo_texture).unwrap_or(NONE)),
        ));
        let emission_texture = texture(m.emission_texture).filter(|_| m.is_emissive());
        data.push(v4(m.emission, bits(emission_texture.unwrap_or(NONE))));
        data.push([
            m.alpha_cutoff.filter(|&c| c > 0.0).unwrap_or(0.0),
            0.0,
            0.0,
            0.0,
        ]);
    }
    let off_textures = data.len() as u32;
    let mut texel_offset = 0u32;
    for t in &scene.textures {
        let n = t.width as usize * t.height as usize;
        let whole = t.texels.len() == n;
        data.push([
            bits(texel_offset),
            bits(if whole { t.width } else { 0 }),
            bits(if whole { t.height } else { 0 }),
            bits(t.sampler.bits()),
        ]);
        texel_offset += t.texels.len().min(n) as u32;
    }
    let off_points = data.len() as u32;
    for (i, l) in scene.point_lights.iter().enumerate() {
        let [fd, fi] = factors(LightId::Point(i as u32));
        let ramp = SpotRamp::of(l.cone.as_ref());
        let radius = match l.radius {
            None => -1.0,
            Some(r) if r > 0.0 => r,
            Some(_) => 0.0,
        };
        data.push(v4(l.position, radius));
        data.push(v4(l.intensity * fd, 0.0));
        data.push(v4(l.intensity * fi, ramp.scale));
        data.push(v4(ramp.axis, ramp.offset));
    }
    let off_dirs = data.len() as u32;
    for (i, l) in scene.directional_lights.iter().enumerate() {
        let [fd, fi] = factors(LightId::Directional(i as u32));
        data.push(v4(-l.direction.normalize(), 0.0));
        data.push(v4(l.irradiance * fd, 0.0));
        data.push(v4(l.irradiance * fi, 0.0));
    }
    let off_emitters = data.len() as u32;
    let probabilities: Vec<f64> = (0..emitters.triangles.len())
        .map(|k| emitters.pick_probability(k))
        .collect();
    let alias = alias_table(&probabilities);
    let mut patterns: Vec<[f32; 4]> = Vec::new();
    for (k, e) in emitters.triangles.iter().enumerate() {
        let (threshold, other) = alias.get(k).copied().unwrap_or((1.0, k as u32));
        let pattern = match emitters.patterns.get(k).and_then(Option::as_ref) {
            Some(p) => {
                let at = patterns.len() as u32 * 4;
                patterns.extend(p.cdf().chunks(4).map(|c| [c[0], c[1], c[2], c[3]]));
                at / 4
            }
            None => NONE,
        };
        data.push(v4(e.corners[0], bits(e.triangle)));
        data.push(v4(e.corners[1], bits(other)));
        data.push(v4(e.corners[2], e.area));
        data.push(v4(e.normal, probabilities[k] as f32));
        data.push([threshold, bits(pattern), bits(e.mesh), 0.0]);
    }
    let off_patterns = data.len() as u32;
    data.extend(patterns);
    let off_meshes = data.len() as u32;
    for i in 0..scene.meshes.len() as u32 {
        let [fd, fi] = factors(LightId::Emissive(i));
        data.push(v4(fd, 0.0));
        data.push(v4(fi, 0.0));
    }
    let off_sky = data.len() as u32;
    let (mut sky_w, mut sky_h, mut sky_factors, mut sky_nee) = (0, 0, [Vec3::ZERO; 2], false);
    if let Some(sky) = scene.sky.as_ref().filter(|s| !s.is_black()) {
        let table = sky.pixel_table();
        let weights: Vec<f64> = table.iter().map(|p| p.2).collect();
        let alias = alias_table(&weights);
        (sky_w, sky_h) = sky.size();
        sky_factors = factors(LightId::Sky);
        sky_nee = !sky.is_uniform();
        // Each row's polar bounds, cos(pi y / h) and cos(pi (y + 1) / h) in f64, ride in the
        // row's first pixel: the shader finds a direction's row by them (WGSL's acos may be
        // as coarse as a few thousandths of a radian, enough to move the horizon).
        let row_cos =
            |y: u32| (std::f64::consts::PI * f64::from(y) / f64::from(sky_h)).cos() as f32;
        for (i, (radiance, pdf, _)) in table.iter().enumerate() {
            let (threshold, other) = alias.get(i).copied().unwrap_or((1.0, i as u32));
            let (x, y) = (i as u32 % sky_w, i as u32 / sky_w);
            let bounds = if x == 0 {
                [row_cos(y), row_cos(y + 1)]
            } else {
                [0.0; 2]
            };
            data.push(v4(*radiance, *pdf));
            data.push([threshold, bits(other), bounds[0], bounds[1]]);
        }
    }

    let has_sky = sky_factors != [Vec3::ZERO; 2];
    let base = Params {
        sky_direct: v4(sky_factors[0], 0.0),
        sky_indirect: v4(sky_factors[1], 0.0),
        flags: fixed.flags | flag(has_sky, FLAG_SKY) | flag(has_sky && sky_nee, FLAG_SKY_NEE),
        n_points: scene.point_lights.len() as u32,
        n_dirs: scene.directional_lights.len() as u32,
        n_emitters: if emitters.is_empty() {
            0
        } else {
            emitters.triangles.len() as u32
        },
        sky_w,
        sky_h,
        off_materials,
        off_textures,
        off_points,
        off_dirs,
        off_emitters,
        off_patterns,
        off_meshes,
        off_sky,
        ..*fixed
    };
    (data, base)
}

// ---- the GPU path tracer as an engine's frame ----
//
// An engine renders ground truth inside its own frame, into its own target, to validate
// what it draws: frames of one view and one light state add samples to one running image
// (a progressive reference); a new view, light state or size starts it again.

/// What a [`PathTracerFrame`] traces per frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathTracerFrameSettings {
    /// Samples per pixel added by each frame (1 to 16).
    pub samples_per_frame: u32,
    /// Samples per pixel after which frames only show the image (at least 1).
    pub max_spp: u32,
    /// Bounce limit.
    pub bounces: Bounces,
    /// Seed of every image.
    pub seed: u64,
}

impl Default for PathTracerFrameSettings {
    fn default() -> Self {
        Self {
            samples_per_frame: 4,
            max_spp: 4096,
            bounces: Bounces::Unlimited,
            seed: 1,
        }
    }
}

/// What the running image was traced for: the view's rays, the light state and the size.
#[derive(Clone, Debug, PartialEq)]
struct Traced {
    camera: [u32; 24],
    lights: u64,
    size: (u32, u32),
}

/// The GPU path tracer in an engine's frame ([`GpuFrame`]). The G-buffer of the frame's
/// inputs is not read (the tracer casts its own camera rays); its size is the target's.
/// After the first frames of a view, a frame creates no GPU object.
pub struct PathTracerFrame {
    ctx: GpuContext,
    scene: Arc<Scene>,
    tracer: GpuPathTracer,
    settings: PathTracerFrameSettings,
    writer: FrameWriter,
    to_texture: PixelsToTexture,
    params: wgpu::Buffer,
    data: KeptBuffer,
    accum: KeptBuffer,
    /// The bind group of the current data and accumulation buffers (their generations).
    bind: Keyed<(u64, u64), wgpu::BindGroup>,
    /// The light state whose data the data buffer holds, and its `Params`.
    packed: Option<(u64, Params)>,
    traced: Option<Traced>,
    spp: u32,
}

impl std::fmt::Debug for PathTracerFrame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PathTracerFrame")
            .field("settings", &self.settings)
            .field("spp", &self.spp)
            .finish_non_exhaustive()
    }
}

impl PathTracerFrame {
    /// Prepares `scene` on `ctx`'s device (the host's, [`GpuContext::from_device`]), as
    /// every method's frame is prepared. Refuses `samples_per_frame` outside 1 to 16 and
    /// `max_spp` 0.
    pub fn prepare(
        ctx: &GpuContext,
        scene: Arc<Scene>,
        settings: PathTracerFrameSettings,
    ) -> Result<Self, crate::Error> {
        if !(1..=SAMPLES_PER_SUBMIT).contains(&settings.samples_per_frame) || settings.max_spp == 0
        {
            return Err(crate::Error::InvalidArgument(format!(
                "path tracer frame: samples_per_frame {} must be 1 to {SAMPLES_PER_SUBMIT} \
                 and max_spp {} at least 1",
                settings.samples_per_frame, settings.max_spp
            )));
        }
        let tracer = GpuPathTracer::new(ctx, &scene, &LightState::default())?;
        Ok(Self {
            ctx: ctx.clone(),
            writer: FrameWriter::new(&ctx.device, 1 << 16),
            to_texture: PixelsToTexture::new(ctx)?,
            params: ctx.frame_buffer(
                "path tracer frame params",
                size_of::<Params>() as u64,
                wgpu::BufferUsages::UNIFORM,
            ),
            data: KeptBuffer::new(
                "path tracer frame data",
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            ),
            accum: KeptBuffer::new(
                "path tracer frame accumulation",
                wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
            ),
            bind: Keyed::new(),
            packed: None,
            traced: None,
            spp: 0,
            scene,
            tracer,
            settings,
        })
    }

    /// Samples per pixel of the image the last frame showed.
    pub fn spp(&self) -> u32 {
        self.spp
    }

    /// Changes the samples per pixel after which frames only show the image (at least 1):
    /// a host that needs an image of exactly `n` samples sets `n` and draws frames until
    /// [`PathTracerFrame::spp`] reaches it.
    pub fn set_max_spp(&mut self, max_spp: u32) {
        self.settings.max_spp = max_spp.max(1);
    }

    /// Records a copy of the running mean (`[r, g, b, 1]` per pixel as `f32`, row-major, the
    /// last frame's size) into the start of `dst` (`COPY_DST`, at least that long): how a
    /// host shows the image in a buffer of its own without a readback. Nothing is recorded
    /// before the first frame or when `dst` is too short.
    pub fn copy_mean_to(&self, encoder: &mut wgpu::CommandEncoder, dst: &wgpu::Buffer) {
        let Some(traced) = &self.traced else {
            return;
        };
        let bytes = u64::from(traced.size.0) * u64::from(traced.size.1) * 16;
        if let Some(src) = self.accum.clone_buffer()
            && dst.size() >= bytes
            && src.size() >= bytes
        {
            encoder.copy_buffer_to_buffer(&src, 0, dst, 0, bytes);
        }
    }
}

impl GpuFrame for PathTracerFrame {
    fn name(&self) -> &str {
        "reference"
    }

    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &FrameInputs<'_>,
        target: &wgpu::Texture,
    ) -> Result<(), crate::Error> {
        let (w, h) = (target.width(), target.height());
        crate::gpu::frame::check_frame_target(target, w, h)?;
        inputs
            .lights
            .check(&self.scene)
            .map_err(|e| crate::Error::InvalidArgument(e.to_string()))?;
        let device = self.ctx.device.clone();
        // The light state's data, packed again only when the state changes.
        let fingerprint = inputs.lights.fingerprint();
        let base = match &self.packed {
            Some((f, p)) if *f == fingerprint => *p,
            _ => {
                let (data, base) = pack_lights(&self.scene, inputs.lights, &self.tracer.fixed);
                let bytes: &[u8] = bytemuck::cast_slice(&data);
                let buffer = self.data.ensure(&device, bytes.len() as u64).clone();
                self.writer.write(encoder, &buffer, 0, bytes);
                self.packed = Some((fingerprint, base));
                base
            }
        };
        let camera = self.tracer.camera_params(inputs.view, &base)?;
        let traced = Traced {
            camera: bytemuck::cast::<[[f32; 4]; 6], [u32; 24]>([
                camera.cam_o0,
                camera.cam_ou,
                camera.cam_ov,
                camera.cam_d0,
                camera.cam_du,
                camera.cam_dv,
            ]),
            lights: fingerprint,
            size: (w, h),
        };
        let pixels = u64::from(w) * u64::from(h);
        let accum = self.accum.ensure(&device, pixels * 32).clone();
        if self.traced.as_ref() != Some(&traced) {
            encoder.clear_buffer(&accum, 0, None);
            self.spp = 0;
            self.traced = Some(traced);
        }
        let n = self
            .settings
            .samples_per_frame
            .min(self.settings.max_spp.saturating_sub(self.spp));
        if n > 0 {
            let key = (self.data.generation(), self.accum.generation());
            let data = self.data.ensure(&device, 16).clone();
            let bind = self
                .bind
                .get_or_make(key, |_| self.tracer.bind(&self.params, &data, &accum))
                .clone();
            // One sample per dispatch (SAMPLES_PER_SUBMIT), each with its own parameters.
            for j in 0..n {
                let params = Params {
                    width: w,
                    height: h,
                    first_sample: self.spp + j,
                    samples: 1,
                    max_vertex: max_vertex(self.settings.bounces),
                    seed_lo: self.settings.seed as u32,
                    seed_hi: (self.settings.seed >> 32) as u32,
                    ..camera
                };
                self.writer
                    .write(encoder, &self.params, 0, bytemuck::bytes_of(&params));
                let mut cp = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("path tracer frame"),
                    timestamp_writes: None,
                });
                cp.set_pipeline(self.tracer.pipeline());
                cp.set_bind_group(0, &bind, &[]);
                cp.dispatch_workgroups(w.div_ceil(WORKGROUP), h.div_ceil(WORKGROUP), 1);
            }
            self.spp += n;
        }
        self.writer.finish(encoder);
        self.to_texture
            .encode(&device, encoder, &accum, target)
            .map_err(crate::Error::from)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Rust `Params` has the WGSL struct's members at the same offsets and size.
    #[test]
    fn params_match_the_shader() {
        let module = PATH_TRACER.compose().unwrap();
        crate::check_layout!(
            &module,
            "Params",
            Params {
                cam_o0,
                cam_ou,
                cam_ov,
                cam_d0,
                cam_du,
                cam_dv,
                sky_direct,
                sky_indirect,
                width,
                height,
                first_sample,
                samples,
                max_vertex,
                seed_lo,
                seed_hi,
                flags,
                scale,
                eps,
                far,
                n_points,
                n_dirs,
                n_emitters,
                sky_w,
                sky_h,
                off_materials,
                off_textures,
                off_points,
                off_dirs,
                off_emitters,
                off_patterns,
                off_meshes,
                off_sky
            }
        )
        .unwrap();
    }

    /// Each entry of an alias table is drawn with its weight's share: the table's implied
    /// probabilities (threshold of its own slot plus the leftovers aliased to it, over the
    /// slot count) equal the weights'.
    #[test]
    fn alias_tables_draw_each_entry_with_its_share() {
        for weights in [
            vec![1.0, 2.0, 3.0, 4.0],
            vec![0.0, 5.0, 0.0, 1e-9, 7.0],
            vec![1.0; 7],
            (0..1000).map(|i| ((i * 37) % 101) as f64).collect(),
        ] {
            let table = alias_table(&weights);
            let n = weights.len() as f64;
            let total: f64 = weights.iter().sum();
            let mut p = vec![0.0f64; weights.len()];
            for (i, &(t, a)) in table.iter().enumerate() {
                p[i] += f64::from(t) / n;
                p[a as usize] += (1.0 - f64::from(t)) / n;
            }
            for (i, w) in weights.iter().enumerate() {
                assert!(
                    (p[i] - w / total).abs() < 1e-6,
                    "entry {i}: drawn with {}, weight share {}",
                    p[i],
                    w / total
                );
            }
        }
        assert!(alias_table(&[0.0, 0.0]).is_empty());
    }
}
