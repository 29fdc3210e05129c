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
use crate::gpu::shader::ShaderPass;
use crate::gpu::{ComputePass, GpuContext, GpuError, WORKGROUP};
use crate::image::Image;
use crate::lights::{Emitters, LightId, LightState, SpotRamp};
use crate::ray::RayScene;
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

/// Samples one invocation traces in one dispatch at most. On lavapipe, 256 to 1 024
/// samples in one invocation's loop came out wrong (a per-sample variance 2-8x too small
/// and a mean 0.5 % off on the corridor, where the same samples in dispatches of 1 to 64
/// agree with each other and with independent seeds; `tests/gpu_reference.rs`, the
/// variance check); 128 was already 4 % low. The cause is not found.
const SAMPLES_PER_INVOCATION: u64 = 16;

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
const NONE: u32 = u32::MAX;

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
    /// A camera ray's origin further than this (in the tree's scaled units) is refused.
    far_origin: f32,
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
        let n = self.spp as f32;
        let (mut mean, mut var) = (Vec::new(), Vec::new());
        for pair in values.chunks_exact(2) {
            mean.push(Vec3::new(pair[0][0], pair[0][1], pair[0][2]));
            let m2 = Vec3::new(pair[1][0], pair[1][1], pair[1][2]);
            var.push(if self.spp < 2 {
                Vec3::ZERO
            } else {
                (m2 / (n - 1.0)).max(Vec3::ZERO)
            });
        }
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

        let emitters = Emitters::new(scene, lights);
        let factors = |id: LightId| {
            let s = lights.get(id);
            [s.direct_factor(), s.indirect_factor()]
        };

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

        // The sections of `data`.
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
        let mut texels: Vec<[f32; 4]> = Vec::with_capacity(texel_count as usize);
        for t in &scene.textures {
            let n = t.width as usize * t.height as usize;
            let whole = t.texels.len() == n;
            data.push([
                bits(texels.len() as u32),
                bits(if whole { t.width } else { 0 }),
                bits(if whole { t.height } else { 0 }),
                bits(t.sampler.bits()),
            ]);
            let alpha = |i: usize| t.alpha.as_ref().and_then(|a| a.get(i)).copied();
            texels.extend(
                t.texels
                    .iter()
                    .take(n)
                    .enumerate()
                    .map(|(i, c)| v4(*c, alpha(i).unwrap_or(1.0))),
            );
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
            for (i, (radiance, pdf, _)) in table.iter().enumerate() {
                let (threshold, other) = alias.get(i).copied().unwrap_or((1.0, i as u32));
                data.push(v4(*radiance, *pdf));
                data.push([threshold, bits(other), 0.0, 0.0]);
            }
        }
        too_big("light and material data", data.len() as u64 * 16)?;

        let sees_emission = scene.meshes.iter().any(|m| {
            m.material_ids.iter().any(|&id| {
                scene
                    .materials
                    .get(id as usize)
                    .is_some_and(|m| m.is_emissive())
            })
        });
        let has_sky = sky_factors != [Vec3::ZERO; 2];
        let flag = |on: bool, bit: u32| if on { bit } else { 0 };
        let flags = flag(sees_emission, FLAG_SEES_EMISSION)
            | flag(has_sky, FLAG_SKY)
            | flag(has_sky && sky_nee, FLAG_SKY_NEE)
            | flag(!rays.cutouts().is_empty(), FLAG_CUTOUTS);
        let base = Params {
            sky_direct: v4(sky_factors[0], 0.0),
            sky_indirect: v4(sky_factors[1], 0.0),
            flags,
            scale,
            eps: extent * 2e-5,
            far: extent * 4.0,
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
            ..Zeroable::zeroed()
        };

        let entries: Vec<wgpu::BindGroupLayoutEntry> = (0..7)
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
            .collect();
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
            far_origin: 1e18,
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
        let bind = self.ctx.validated(|| {
            self.pass.bind(
                &self.ctx.device,
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
        Ok(GpuAccumulator {
            width,
            height,
            spp: 0,
            accum,
            params,
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
        let camera = self.camera(view)?;
        let start = Instant::now();
        let samples = samples.min(u32::MAX - acc.spp);
        let pixels = u64::from(acc.width) * u64::from(acc.height);
        let per_dispatch = (PATHS_PER_DISPATCH / pixels).clamp(1, SAMPLES_PER_INVOCATION) as u32;
        let mut done = 0;
        while done < samples {
            let n = per_dispatch.min(samples - done);
            let params = Params {
                width: acc.width,
                height: acc.height,
                first_sample: acc.spp + done,
                samples: n,
                max_vertex: match bounces {
                    Bounces::Limited(n) => n,
                    Bounces::Unlimited => u32::MAX - 1,
                },
                seed_lo: seed as u32,
                seed_hi: (seed >> 32) as u32,
                ..camera
            };
            self.ctx.validated(|| {
                self.ctx
                    .queue
                    .write_buffer(&acc.params, 0, bytemuck::bytes_of(&params));
                self.ctx.submit_encoded(|encoder| {
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

    /// The shader's constants with `view`'s camera rays: origin `o0 + ou u + ov v`,
    /// direction `d0 + du u + dv v` (normalised in the shader), as [`View::ray`].
    fn camera(&self, view: &View) -> Result<Params, GpuError> {
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
            ..self.base
        })
    }
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

#[cfg(test)]
mod tests {
    use super::*;

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
