//! The CPU G-buffer rasteriser: tiled, rayon-parallel, watertight.
//!
//! # Pipeline
//!
//! 1. **Set-up** (rayon over fixed chunks of triangles): transformation by the
//!    view-projection matrix (shared vertices give bit-identical results), outcode
//!    frustum rejection, clipping
//!    against the near plane (clip `z >= 0`, as the GPU does) and, for vertices that would
//!    land absurdly far outside the image, against a guard band; fan triangulation of the
//!    clipped polygon; projection to screen space and snapping to a fixed-point grid of
//!    1/256 pixel ([`SUBPIXEL_BITS`], the precision of most GPUs); rejection of zero-area
//!    triangles and of triangles that cover no pixel centre; binning into
//!    [`TILE`] x [`TILE`] pixel tiles. Each chunk bins its own triangles, in order.
//! 2. **Visibility** (rayon over bands of tile rows): per tile, triangles in global order
//!    are scanned with exact 64-bit integer edge functions; a pixel centre is covered when
//!    all three edge functions are positive, or zero on a *top* or *left* edge (the
//!    top-left fill rule, so a pixel on an edge shared by two triangles belongs to exactly
//!    one of them). The depth test is `z < stored` on clip-space depth interpolated linearly
//!    in screen space, the buffer cleared to 1 (exactly the GPU pipeline's `Less` test on a
//!    depth attachment cleared to 1); ties keep the earlier triangle, like GPU draw order.
//! 3. **Resolve**: only the winning triangle of each pixel is shaded: perspective-correct
//!    barycentrics from the unsnapped clip-space vertices (homogeneous 2D barycentric
//!    planes, as GPUs interpolate), mapped back to the original (unclipped) triangle,
//!    interpolate the vertex normals (renormalised; the face normal where they cancel),
//!    the UVs (bilinear albedo texture lookup) and the linear depth.
//!
//! The fill rule makes the *snapped* mesh watertight: no pixel centre on a shared edge is
//! lost or covered twice, exact ties included. A sub-pixel sliver can flip orientation
//! when its vertices snap (far away, at grazing angles) and then overlaps its neighbours,
//! exactly as on GPUs; the depth test still gives every pixel one triangle.
//!
//! Triangles are two-sided: nothing is culled by winding, and the normal is flipped to face
//! the viewer when the triangle's geometric normal faces away from the eye (the
//! convention of [`scene_core::gbuffer::RayCastRenderer`]). Results are bit-identical for
//! any number of threads: chunk boundaries do not depend on the thread count, each tile is
//! processed by one thread in global triangle order, and every pixel is computed by the
//! same sequence of operations.

use std::sync::Arc;

use glam::{Vec2, Vec3, Vec4};
use rayon::prelude::*;
use scene_core::view::Projection;
use scene_core::{BACKGROUND_ID, Error, GBuffer, GBufferRenderer, Scene, View, ViewTarget};

/// Tile edge in pixels.
pub const TILE: u32 = 32;
/// Sub-pixel precision of snapped vertex positions: 8 bits, 1/256 pixel.
pub const SUBPIXEL_BITS: u32 = 8;
/// Largest width or height a renderer of this crate accepts.
pub const MAX_TARGET_SIZE: u32 = 16384;

const SUB: i64 = 1 << SUBPIXEL_BITS;
const HALF: i64 = SUB / 2;
/// Triangles per set-up chunk (at least); fixed so results do not depend on thread count.
const MIN_CHUNK: usize = 4096;
/// At most this many chunks, so per-chunk bins stay small for huge scenes.
const MAX_CHUNKS: usize = 256;
/// The guard band keeps screen coordinates within about +-2^19 pixels (vertices beyond
/// +-2^21 are refused), so snapped coordinates stay below 2^29 in magnitude and edge
/// functions below 2^61: no 64-bit overflow.
const GUARD_PIXELS: f32 = (1u32 << 20) as f32;

/// The CPU rasteriser. [`CpuRasterizer::render_gbuffer`] draws any scene directly; as a
/// [`GBufferRenderer`] it holds the scene it was prepared with.
///
/// ```
/// use gbuffer::CpuRasterizer;
/// use scene_core::{builtin, GBufferRenderer, View};
///
/// let scene = builtin::scene("cornell").unwrap();
/// let view = View::from_camera(&scene.cameras[0]);
/// let g = CpuRasterizer::new().render(&scene, &view, 64, 64).unwrap();
/// assert_eq!(g.len(), 64 * 64);
/// // The published camera sees the inside of the box almost everywhere.
/// assert!(g.background_mask().iter().filter(|&&b| b).count() < 64 * 4);
/// ```
#[derive(Clone, Debug, Default)]
pub struct CpuRasterizer {
    prepared: Option<Arc<Scene>>,
    /// The prepared scene's span bounds (frustum culling of whole spans).
    bounds: Option<Arc<SpanBounds>>,
}

/// Triangles per culling span: the set-up skips a span of a prepared scene whose bounding
/// box lies outside the view frustum.
const CULL_SPAN: usize = 256;

/// The bounding box of every [`CULL_SPAN`] triangles of each mesh of a prepared scene
/// (`None`: a span without a finite, in-range vertex, which is set up as usual).
#[derive(Debug)]
struct SpanBounds {
    meshes: Vec<Vec<Option<(Vec3, Vec3)>>>,
}

impl SpanBounds {
    fn of(scene: &Scene) -> Self {
        let meshes = scene
            .meshes
            .iter()
            .map(|mesh| {
                mesh.indices
                    .par_chunks(CULL_SPAN)
                    .map(|span| {
                        let mut b: Option<(Vec3, Vec3)> = None;
                        for &i in span.iter().flatten() {
                            let &p = mesh.positions.get(i as usize)?;
                            if !p.is_finite() {
                                return None;
                            }
                            b = Some(b.map_or((p, p), |(lo, hi)| (lo.min(p), hi.max(p))));
                        }
                        b
                    })
                    .collect()
            })
            .collect();
        Self { meshes }
    }
}

impl CpuRasterizer {
    /// The rasteriser, with no scene prepared.
    pub fn new() -> Self {
        Self::default()
    }

    /// Renders `scene` from `view` into a `width x height` G-buffer on the calling rayon
    /// pool (see the module documentation for the conventions).
    ///
    /// Errors on a zero or oversized target ([`MAX_TARGET_SIZE`]) and on a view with
    /// non-finite data or `0 < near < far` violated. Triangles with out-of-range indices
    /// or material ids, or non-finite positions, are skipped rather than trusted.
    pub fn render_gbuffer(
        &self,
        scene: &Scene,
        view: &View,
        width: u32,
        height: u32,
    ) -> Result<GBuffer, Error> {
        check_target(view, width, height)?;
        let n = width as usize * height as usize;
        // Fresh memory is faulted in by the writing threads, not serially.
        let mut g = GBuffer {
            width,
            height,
            albedo: par_filled(n, Vec4::ZERO),
            normal: par_filled(n, Vec3::ZERO),
            depth: par_filled(n, 1.0),
            triangle_id: par_filled(n, BACKGROUND_ID),
        };
        self.render_into(scene, view, &mut g)?;
        Ok(g)
    }

    /// The span bounds when `scene` is the prepared scene itself.
    fn bounds_for(&self, scene: &Scene) -> Option<&SpanBounds> {
        let prepared = self.prepared.as_ref()?;
        std::ptr::eq(prepared.as_ref(), scene)
            .then_some(self.bounds.as_deref())
            .flatten()
    }

    /// Renders into an existing G-buffer of `target.width x target.height`, overwriting
    /// every pixel (its channel vectors are resized if their lengths do not match). Reusing
    /// one target across frames avoids allocating and faulting in ~36 bytes per pixel each
    /// frame, which at 1024x768 costs more than rasterising a simple scene.
    pub fn render_into(
        &self,
        scene: &Scene,
        view: &View,
        target: &mut GBuffer,
    ) -> Result<(), Error> {
        let (width, height) = (target.width, target.height);
        check_target(view, width, height)?;
        let n = width as usize * height as usize;
        target.albedo.resize(n, Vec4::ZERO);
        target.normal.resize(n, Vec3::ZERO);
        target.depth.resize(n, 1.0);
        target.triangle_id.resize(n, BACKGROUND_ID);
        let bounds = self.bounds_for(scene);
        let setup = Setup::run(scene, view, width, height, bounds);
        let band = (TILE * width) as usize;
        target
            .albedo
            .par_chunks_mut(band)
            .zip(target.normal.par_chunks_mut(band))
            .zip(target.depth.par_chunks_mut(band))
            .zip(target.triangle_id.par_chunks_mut(band))
            .enumerate()
            .for_each(|(ty, (((albedo, normal), depth), ids))| {
                let mut out = BandOut {
                    albedo,
                    normal,
                    depth,
                    ids,
                };
                setup.shade_band(scene, ty as u32, &mut out);
            });
        Ok(())
    }

    /// Diagnostic: for each pixel (row-major), how many triangle fragments cover its centre
    /// after clipping, with no depth test (fragments beyond the far plane are not counted).
    /// A closed or tiling mesh seen from one side gives exactly 1 where it covers the image:
    /// this is how the fill rule is tested.
    pub fn coverage(
        &self,
        scene: &Scene,
        view: &View,
        width: u32,
        height: u32,
    ) -> Result<Vec<u32>, Error> {
        check_target(view, width, height)?;
        let setup = Setup::run(scene, view, width, height, self.bounds_for(scene));
        let mut counts = vec![0u32; width as usize * height as usize];
        counts
            .par_chunks_mut((TILE * width) as usize)
            .enumerate()
            .for_each(|(ty, band)| setup.count_band(ty as u32, band));
        Ok(counts)
    }
}

impl GBufferRenderer for CpuRasterizer {
    fn name(&self) -> &str {
        "cpu"
    }

    /// Keeps the scene and the bounds of its spans of triangles, which let each view skip
    /// the spans outside its frustum.
    fn prepare(&mut self, scene: Arc<Scene>) -> Result<(), Error> {
        self.bounds = Some(Arc::new(SpanBounds::of(&scene)));
        self.prepared = Some(scene);
        Ok(())
    }

    fn prepared_scene(&self) -> Option<&Arc<Scene>> {
        self.prepared.as_ref()
    }

    fn render_views(&mut self, views: &[ViewTarget]) -> Result<Vec<GBuffer>, Error> {
        let Some(scene) = self.prepared.as_ref() else {
            return Err(Error::NotPrepared("the CPU rasteriser".into()));
        };
        views
            .iter()
            .map(|t| self.render_gbuffer(scene, &t.view, t.width, t.height))
            .collect()
    }

    /// Draws `scene` directly (nothing is prepared or copied).
    fn render(
        &mut self,
        scene: &Scene,
        view: &View,
        width: u32,
        height: u32,
    ) -> Result<GBuffer, Error> {
        self.render_gbuffer(scene, view, width, height)
    }
}

/// Checks a render target size and a view; shared by the CPU and GPU renderers.
pub(crate) fn check_target(view: &View, width: u32, height: u32) -> Result<(), Error> {
    if width == 0 || height == 0 {
        return Err(Error::InvalidArgument(format!(
            "G-buffer size {width}x{height}: zero-size targets are not allowed"
        )));
    }
    if width > MAX_TARGET_SIZE || height > MAX_TARGET_SIZE {
        return Err(Error::InvalidArgument(format!(
            "G-buffer size {width}x{height} exceeds the maximum of {MAX_TARGET_SIZE} per side"
        )));
    }
    check_view(view)
}

/// Checks that a view can be rasterised: finite data, unit-ish frame, `0 < near < far`,
/// a projection window of non-zero size.
pub(crate) fn check_view(view: &View) -> Result<(), Error> {
    let (l, r, b, t) = match view.projection {
        Projection::Perspective {
            left,
            right,
            bottom,
            top,
        }
        | Projection::Orthographic {
            left,
            right,
            bottom,
            top,
        } => (left, right, bottom, top),
    };
    let finite = view.eye.is_finite()
        && view.forward.is_finite()
        && view.up.is_finite()
        && [l, r, b, t, view.near, view.far]
            .iter()
            .all(|x| x.is_finite());
    if !finite {
        return Err(Error::InvalidArgument(
            "view has non-finite eye, frame, window or planes".into(),
        ));
    }
    if !(view.near > 0.0 && view.far > view.near) {
        return Err(Error::InvalidArgument(format!(
            "view needs 0 < near < far (near {}, far {})",
            view.near, view.far
        )));
    }
    if r <= l || t <= b {
        return Err(Error::InvalidArgument(format!(
            "view window is empty (left {l}, right {r}, bottom {b}, top {t})"
        )));
    }
    // Beyond this f32 depth rounds every surface to the far plane and nothing is drawn: a
    // typed refusal rather than a black frame (cameras are refused at load alike).
    if view.far / view.near > scene_core::scene::DEPTH_RANGE_MAX {
        return Err(Error::InvalidArgument(format!(
            "view planes near {:e} and far {:e}: far / near is above {:e}, beyond what f32 \
             depth resolves",
            view.near,
            view.far,
            scene_core::scene::DEPTH_RANGE_MAX
        )));
    }
    if (view.forward.length() - 1.0).abs() > 1e-3
        || (view.up.length() - 1.0).abs() > 1e-3
        || view.forward.dot(view.up).abs() > 1e-3
    {
        return Err(Error::InvalidArgument(
            "view forward and up must be orthonormal".into(),
        ));
    }
    Ok(())
}

/// A vector of `n` copies of `value`, written by the rayon pool.
fn par_filled<T: Copy + Send + Sync>(n: usize, value: T) -> Vec<T> {
    let mut v = Vec::with_capacity(n);
    v.par_extend(rayon::iter::repeat_n(value, n));
    v
}

/// A clip-space vertex during clipping, with its barycentric coordinates in the original
/// triangle.
#[derive(Clone, Copy, Debug)]
struct ClipVertex {
    clip: Vec4,
    bary: Vec3,
}

/// A triangle ready for scan conversion.
#[derive(Clone, Copy, Debug)]
struct Tri {
    /// Snapped screen positions (1/256 pixel, y down), counter-clockwise on screen so the
    /// doubled area is positive.
    xy: [[i32; 2]; 3],
    /// Clip-space depth `z / w` per vertex.
    z: [f32; 3],
    /// Homogeneous barycentric planes: for the pixel centre at NDC `(x, y)`, the
    /// perspective-correct barycentric weight of vertex `k` is proportional to
    /// `plane[k] . (x, y, 1)` (the cross product of the other two vertices' clip-space
    /// `(x, y, w)`). Interpolation uses these unsnapped planes, like GPUs do; only coverage
    /// and the depth test use the snapped positions.
    plane: [Vec3; 3],
    /// Linear depth of the original triangle's three vertices (original order).
    depth: [f32; 3],
    /// Index of the triangle in its mesh.
    local: u32,
    /// The original triangle shows its back to the view: flip its normals.
    flip: bool,
    /// [`BARY_IDENTITY`], [`BARY_SWAPPED`], or an index into the chunk's `barys`.
    bary: u32,
    /// Pixel bounding box `[x0, y0, x1, y1]`, inclusive, inside the image.
    bbox: [u16; 4],
}

/// The triangle's vertices are the original ones, in order.
const BARY_IDENTITY: u32 = u32::MAX;
/// The original vertices with the second and third exchanged.
const BARY_SWAPPED: u32 = u32::MAX - 1;

/// The set-up output of one chunk of triangles of one mesh.
struct Chunk {
    mesh: u32,
    tris: Vec<Tri>,
    /// Barycentric rows (one per set-up vertex) of clipped triangles.
    barys: Vec<[Vec3; 3]>,
    /// `bins[bin_start[t]..bin_start[t + 1]]` are the indices into `tris` touching tile `t`.
    bin_start: Vec<u32>,
    bins: Vec<u32>,
}

/// Everything the tile passes need.
struct Setup {
    width: u32,
    height: u32,
    /// `(2 / width, 2 / height)`: pixel to NDC.
    ndc_scale: Vec2,
    tiles_x: u32,
    chunks: Vec<Chunk>,
    offsets: Vec<u32>,
    /// Alpha-masked triangles: their fragments in a hole are discarded before the depth
    /// test, as the GPU pass discards them.
    cutouts: scene_core::Cutouts,
}

/// Edge-function coefficients of one edge.
#[derive(Clone, Copy)]
struct Edge {
    /// `E(x, y) = a (x - x0) + b (y - y0)` in 1/256 pixel units.
    a: i64,
    b: i64,
    x0: i64,
    y0: i64,
    /// 0 for top and left edges, -1 otherwise.
    bias: i64,
}

impl Edge {
    /// The edge from `p` to `q`; the interior (for a triangle with positive doubled area)
    /// is where `E > 0`.
    fn new(p: [i32; 2], q: [i32; 2]) -> Self {
        let (dx, dy) = (q[0] as i64 - p[0] as i64, q[1] as i64 - p[1] as i64);
        // With y pointing down, the interior of an edge with dy < 0 lies to its right (a
        // left edge); a horizontal edge with dx > 0 has the interior below it (a top edge).
        let top_left = dy < 0 || (dy == 0 && dx > 0);
        Self {
            a: -dy,
            b: dx,
            x0: p[0] as i64,
            y0: p[1] as i64,
            bias: if top_left { 0 } else { -1 },
        }
    }

    /// The raw edge function at a point (1/256 pixel units).
    fn at(&self, x: i64, y: i64) -> i64 {
        self.a * (x - self.x0) + self.b * (y - self.y0)
    }
}

/// A screen coordinate in pixels to the nearest 1/256 pixel (ties away from zero, like
/// `f64::round`, without the libm call).
#[inline]
fn snap(v: f64) -> i32 {
    let f = v * SUB as f64;
    (f + 0.5f64.copysign(f)) as i32
}

fn pixel_centre(p: u32) -> i64 {
    p as i64 * SUB + HALF
}

/// Output slices of one band of tile rows.
struct BandOut<'a> {
    albedo: &'a mut [Vec4],
    normal: &'a mut [Vec3],
    depth: &'a mut [f32],
    ids: &'a mut [u32],
}

impl Setup {
    fn run(
        scene: &Scene,
        view: &View,
        width: u32,
        height: u32,
        bounds: Option<&SpanBounds>,
    ) -> Setup {
        let total = scene.triangle_count();
        let chunk_size = MIN_CHUNK.max(total.div_ceil(MAX_CHUNKS));
        let mut specs = Vec::new();
        for (mi, mesh) in scene.meshes.iter().enumerate() {
            let n = mesh.indices.len();
            let mut start = 0;
            while start < n {
                let end = (start + chunk_size).min(n);
                specs.push((mi, start, end));
                start = end;
            }
        }
        let ctx = SetupContext::new(view, width, height);
        let chunks: Vec<Chunk> = specs
            .par_iter()
            .map(|&(mi, start, end)| {
                let spans = bounds.and_then(|b| b.meshes.get(mi)).map(|s| &s[..]);
                ctx.setup_chunk(scene, mi, start, end, spans)
            })
            .collect();
        Setup {
            width,
            height,
            ndc_scale: Vec2::new(2.0 / width as f32, 2.0 / height as f32),
            tiles_x: ctx.tiles_x,
            chunks,
            offsets: scene.mesh_offsets(),
            cutouts: scene_core::Cutouts::of(scene),
        }
    }

    /// The pixel rectangle `[x0, y0, x1, y1]` (inclusive) of tile `(tx, ty)`.
    fn tile_rect(&self, tx: u32, ty: u32) -> [u32; 4] {
        [
            tx * TILE,
            ty * TILE,
            ((tx + 1) * TILE).min(self.width) - 1,
            ((ty + 1) * TILE).min(self.height) - 1,
        ]
    }

    /// Calls `f(chunk index, triangle index)` for every triangle binned to tile `t`, in
    /// global triangle order.
    fn for_each_in_tile(&self, t: usize, mut f: impl FnMut(usize, usize)) {
        for (ci, chunk) in self.chunks.iter().enumerate() {
            let (s, e) = (chunk.bin_start[t] as usize, chunk.bin_start[t + 1] as usize);
            for &ti in &chunk.bins[s..e] {
                f(ci, ti as usize);
            }
        }
    }

    /// Visibility and resolve for one band of tiles; writes every pixel of the band's rows.
    fn shade_band(&self, scene: &Scene, ty: u32, out: &mut BandOut<'_>) {
        let tile_px = (TILE * TILE) as usize;
        let mut zbuf = vec![1.0f32; tile_px];
        let mut winner = vec![u64::MAX; tile_px];
        let mut cache = ShadeCache::default();
        let w = self.width as usize;
        for tx in 0..self.tiles_x {
            let rect = self.tile_rect(tx, ty);
            zbuf.fill(1.0);
            winner.fill(u64::MAX);
            let t = (ty * self.tiles_x + tx) as usize;
            self.for_each_in_tile(t, |ci, ti| {
                let chunk = &self.chunks[ci];
                let tri = &chunk.tris[ti];
                let key = ((ci as u64) << 32) | ti as u64;
                let id = self.offsets[chunk.mesh as usize] + tri.local;
                let masked = self.cutouts.is_masked(id);
                scan(tri, rect, |lx, ly, z| {
                    let i = ly * TILE as usize + lx;
                    if z < zbuf[i]
                        && (!masked
                            || self.exists(
                                chunk,
                                tri,
                                id,
                                rect[0] + lx as u32,
                                rect[1] + ly as u32,
                            ))
                    {
                        zbuf[i] = z;
                        winner[i] = key;
                    }
                });
            });
            for ly in 0..=(rect[3] - rect[1]) as usize {
                for lx in 0..=(rect[2] - rect[0]) as usize {
                    let key = winner[ly * TILE as usize + lx];
                    let (px, py) = (rect[0] + lx as u32, rect[1] + ly as u32);
                    let o = ly * w + px as usize;
                    let shaded = if key == u64::MAX {
                        None
                    } else {
                        self.resolve(scene, &mut cache, key, px, py)
                    };
                    let (a, n, d, id) =
                        shaded.unwrap_or((Vec4::ZERO, Vec3::ZERO, 1.0, BACKGROUND_ID));
                    out.albedo[o] = a;
                    out.normal[o] = n;
                    out.depth[o] = d;
                    out.ids[o] = id;
                }
            }
        }
    }

    /// Fragment counts for one band of tiles.
    fn count_band(&self, ty: u32, band: &mut [u32]) {
        let w = self.width as usize;
        for tx in 0..self.tiles_x {
            let rect = self.tile_rect(tx, ty);
            let t = (ty * self.tiles_x + tx) as usize;
            self.for_each_in_tile(t, |ci, ti| {
                scan(&self.chunks[ci].tris[ti], rect, |lx, ly, z| {
                    if z < 1.0 {
                        band[ly * w + rect[0] as usize + lx] += 1;
                    }
                });
            });
        }
    }

    /// The perspective-correct barycentric weights of the source triangle's vertices 0, 1
    /// and 2 at the centre of pixel `(px, py)` (`None` where they are not finite).
    fn barycentric(&self, chunk: &Chunk, tri: &Tri, px: u32, py: u32) -> Option<Vec3> {
        let ndc = Vec3::new(
            (px as f32 + 0.5) * self.ndc_scale.x - 1.0,
            1.0 - (py as f32 + 0.5) * self.ndc_scale.y,
            1.0,
        );
        let q = Vec3::new(
            tri.plane[0].dot(ndc),
            tri.plane[1].dot(ndc),
            tri.plane[2].dot(ndc),
        );
        let inv = 1.0 / (q.x + q.y + q.z);
        if !inv.is_finite() {
            return None;
        }
        let b = q * inv;
        Some(match tri.bary {
            BARY_IDENTITY => b,
            BARY_SWAPPED => Vec3::new(b.x, b.z, b.y),
            i => {
                let rows = chunk.barys[i as usize];
                rows[0] * b.x + rows[1] * b.y + rows[2] * b.z
            }
        })
    }

    /// True where masked triangle `id` exists at pixel `(px, py)` (its alpha reaches the
    /// cutoff at the pixel centre).
    fn exists(&self, chunk: &Chunk, tri: &Tri, id: u32, px: u32, py: u32) -> bool {
        self.barycentric(chunk, tri, px, py)
            .is_some_and(|b| self.cutouts.opaque(id, glam::Vec2::new(b.y, b.z)))
    }

    /// Shades the winning triangle `key` at pixel `(px, py)`: albedo with mask, normal
    /// facing the viewer, linear depth, global triangle id. `cache` keeps the per-triangle
    /// data of the last triangle shaded (neighbouring pixels mostly share it).
    fn resolve(
        &self,
        scene: &Scene,
        cache: &mut ShadeCache,
        key: u64,
        px: u32,
        py: u32,
    ) -> Option<(Vec4, Vec3, f32, u32)> {
        let chunk = &self.chunks[(key >> 32) as usize];
        let tri = &chunk.tris[(key & 0xffff_ffff) as usize];
        if cache.key != key {
            *cache = ShadeCache::new(scene, chunk, tri, key, &self.offsets);
        }
        let bw = self.barycentric(chunk, tri, px, py)?.to_array();
        let depth = tri.depth[0] * bw[0] + tri.depth[1] * bw[1] + tri.depth[2] * bw[2];
        let mut n =
            (cache.normals[0] * bw[0] + cache.normals[1] * bw[1] + cache.normals[2] * bw[2])
                .normalize_or_zero();
        if n == Vec3::ZERO {
            n = cache.face_normal;
        }
        if tri.flip {
            n = -n;
        }
        let albedo = match (cache.constant_albedo, cache.uvs) {
            (Some(a), _) => a,
            (None, Some(uv)) => {
                let uv = uv[0] * bw[0] + uv[1] * bw[1] + uv[2] * bw[2];
                scene.albedo_at(cache.material, Some(uv))
            }
            (None, None) => scene.albedo_at(cache.material, None),
        };
        let albedo = match cache.colors {
            Some(c) => albedo * (c[0] * bw[0] + c[1] * bw[1] + c[2] * bw[2]),
            None => albedo,
        };
        Some((albedo.extend(1.0), n, depth, cache.id))
    }
}

/// Per-triangle shading data, cached across neighbouring pixels.
struct ShadeCache {
    key: u64,
    normals: [Vec3; 3],
    face_normal: Vec3,
    uvs: Option<[Vec2; 3]>,
    /// Vertex colours, when the mesh has them.
    colors: Option<[Vec3; 3]>,
    material: u32,
    /// The albedo when it does not vary over the triangle (no texture or no UVs).
    constant_albedo: Option<Vec3>,
    id: u32,
}

impl Default for ShadeCache {
    fn default() -> Self {
        Self {
            key: u64::MAX,
            normals: [Vec3::ZERO; 3],
            face_normal: Vec3::ZERO,
            uvs: None,
            colors: None,
            material: 0,
            constant_albedo: None,
            id: BACKGROUND_ID,
        }
    }
}

impl ShadeCache {
    fn new(scene: &Scene, chunk: &Chunk, tri: &Tri, key: u64, offsets: &[u32]) -> Self {
        let mesh = &scene.meshes[chunk.mesh as usize];
        let idx = mesh.indices[tri.local as usize];
        let p = idx.map(|i| mesh.positions[i as usize]);
        let material = mesh.material_ids[tri.local as usize];
        let uvs = mesh
            .uvs
            .as_ref()
            .map(|uvs| idx.map(|i| uvs.get(i as usize).copied().unwrap_or(Vec2::ZERO)));
        let textured = scene.materials[material as usize].albedo_texture.is_some();
        Self {
            key,
            normals: idx.map(|i| mesh.normals.get(i as usize).copied().unwrap_or(Vec3::ZERO)),
            face_normal: (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero(),
            uvs,
            colors: mesh
                .colors
                .as_ref()
                .map(|c| idx.map(|i| c.get(i as usize).copied().unwrap_or(Vec3::ONE))),
            material,
            constant_albedo: (!textured || uvs.is_none()).then(|| scene.albedo_at(material, None)),
            id: offsets[chunk.mesh as usize] + tri.local,
        }
    }
}

/// True when a triangle with (unnormalised) geometric normal `ng` through `p0` shows its
/// back to the view, so its shading normal must be flipped: the sign of `ng . (p0 - eye)`
/// for perspective views (constant over the triangle's plane), of `ng . forward` for
/// orthographic ones.
pub(crate) fn facing_away(view: &View, ng: Vec3, p0: Vec3) -> bool {
    match view.projection {
        Projection::Perspective { .. } => ng.dot(p0 - view.eye) > 0.0,
        Projection::Orthographic { .. } => ng.dot(view.forward) > 0.0,
    }
}

/// Calls `f(local x, local y, z)` for every pixel of `rect` whose centre `tri` covers (top-
/// left rule), with the fragment's clip-space depth.
fn scan(tri: &Tri, rect: [u32; 4], mut f: impl FnMut(usize, usize, f32)) {
    let x0 = (tri.bbox[0] as u32).max(rect[0]);
    let y0 = (tri.bbox[1] as u32).max(rect[1]);
    let x1 = (tri.bbox[2] as u32).min(rect[2]);
    let y1 = (tri.bbox[3] as u32).min(rect[3]);
    if x0 > x1 || y0 > y1 {
        return;
    }
    let [v0, v1, v2] = tri.xy;
    let edges = [Edge::new(v1, v2), Edge::new(v2, v0), Edge::new(v0, v1)];
    let (sx, sy) = (pixel_centre(x0), pixel_centre(y0));
    let raw = edges.map(|e| e.at(sx, sy));
    let area = (raw[0] + raw[1] + raw[2]) as f64;
    // Depth plane: z = sum_k E_k z_k / area, stepped exactly like the edge functions.
    let zk = tri.z.map(f64::from);
    let z_at = |e: [f64; 3]| (e[0] * zk[0] + e[1] * zk[1] + e[2] * zk[2]) / area;
    let z_start = z_at(raw.map(|v| v as f64));
    let dzdx = z_at(edges.map(|e| (e.a * SUB) as f64));
    let dzdy = z_at(edges.map(|e| (e.b * SUB) as f64));
    let mut row = [
        raw[0] + edges[0].bias,
        raw[1] + edges[1].bias,
        raw[2] + edges[2].bias,
    ];
    let step_x = edges.map(|e| e.a * SUB);
    let step_y = edges.map(|e| e.b * SUB);
    let mut z_row = z_start;
    for y in y0..=y1 {
        let mut e = row;
        let mut z = z_row;
        for x in x0..=x1 {
            if (e[0] | e[1] | e[2]) >= 0 {
                f((x - rect[0]) as usize, (y - rect[1]) as usize, z as f32);
            }
            e[0] += step_x[0];
            e[1] += step_x[1];
            e[2] += step_x[2];
            z += dzdx;
        }
        row[0] += step_y[0];
        row[1] += step_y[1];
        row[2] += step_y[2];
        z_row += dzdy;
    }
}

/// Constants of the set-up stage.
struct SetupContext {
    view_proj: glam::Mat4,
    view: View,
    width: u32,
    height: u32,
    tiles_x: u32,
    tiles: usize,
    /// Guard band half-extents in NDC units.
    guard_x: f32,
    guard_y: f32,
}

/// The plane `dist(clip) >= 0` of one clip stage.
#[derive(Clone, Copy)]
enum Plane {
    Near,
    Guard { axis: usize, sign: f32, g: f32 },
}

impl Plane {
    fn dist(self, c: Vec4) -> f32 {
        match self {
            Plane::Near => c.z,
            Plane::Guard { axis, sign, g } => g * c.w - sign * c[axis],
        }
    }
}

/// Orders two clip vertices canonically (lexicographic on the bit patterns of their clip
/// coordinates), so an edge shared by two triangles is cut at bit-identical points.
fn canonical_first(a: &ClipVertex, b: &ClipVertex) -> bool {
    let ka = a.clip.to_array().map(f32::to_bits);
    let kb = b.clip.to_array().map(f32::to_bits);
    ka <= kb
}

/// Sutherland-Hodgman against one plane.
fn clip_polygon(input: &[ClipVertex], plane: Plane, out: &mut Vec<ClipVertex>) {
    out.clear();
    let n = input.len();
    for i in 0..n {
        let a = input[i];
        let b = input[(i + 1) % n];
        let (da, db) = (plane.dist(a.clip), plane.dist(b.clip));
        if da >= 0.0 {
            out.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            let (p, q, dp, dq) = if canonical_first(&a, &b) {
                (a, b, da, db)
            } else {
                (b, a, db, da)
            };
            let t = dp / (dp - dq);
            out.push(ClipVertex {
                clip: p.clip + (q.clip - p.clip) * t,
                bary: p.bary + (q.bary - p.bary) * t,
            });
        }
    }
}

impl SetupContext {
    /// The set-up of `view` into a `width x height` target.
    fn new(view: &View, width: u32, height: u32) -> Self {
        let tiles_x = width.div_ceil(TILE);
        Self {
            view_proj: view.view_projection(),
            view: *view,
            width,
            height,
            tiles_x,
            tiles: (tiles_x * height.div_ceil(TILE)) as usize,
            guard_x: GUARD_PIXELS / width as f32,
            guard_y: GUARD_PIXELS / height as f32,
        }
    }

    /// Sets up triangles `start..end` of mesh `mesh_index`; with `spans` (the mesh's
    /// [`SpanBounds`]), a span whose box is outside the frustum is skipped whole.
    fn setup_chunk(
        &self,
        scene: &Scene,
        mesh_index: usize,
        start: usize,
        end: usize,
        spans: Option<&[Option<(Vec3, Vec3)>]>,
    ) -> Chunk {
        let mesh = &scene.meshes[mesh_index];
        let mut chunk = Chunk {
            mesh: mesh_index as u32,
            // Most triangles give one set-up triangle at most; untouched capacity costs
            // only address space.
            tris: Vec::with_capacity(end - start),
            barys: Vec::new(),
            bin_start: Vec::new(),
            bins: Vec::new(),
        };
        let mut poly = Vec::with_capacity(12);
        let mut tmp = Vec::with_capacity(12);
        let mut skip_to = start;
        for local in start..end {
            // A whole span outside the frustum: its triangles would each be rejected by
            // their outcodes below (the same bits, without the work).
            if local < skip_to {
                continue;
            }
            if local.is_multiple_of(CULL_SPAN)
                && let Some(Some((lo, hi))) = spans.and_then(|s| s.get(local / CULL_SPAN))
                && self.box_outside(*lo, *hi)
            {
                skip_to = local + CULL_SPAN;
                continue;
            }
            let idx = mesh.indices[local];
            let material_ok = mesh
                .material_ids
                .get(local)
                .is_some_and(|&m| (m as usize) < scene.materials.len());
            if !material_ok
                || idx.iter().any(|&i| i as usize >= mesh.positions.len())
                || idx
                    .iter()
                    .any(|&i| mesh.uvs.as_ref().is_some_and(|uvs| i as usize >= uvs.len()))
            {
                continue;
            }
            // Shared vertices transform to bit-identical clip coordinates (same inputs,
            // same operations), which the watertight set-up relies on.
            let p = idx.map(|i| mesh.positions[i as usize]);
            let c = p.map(|p| self.view_proj * p.extend(1.0));
            if !c.iter().all(|v| v.is_finite()) {
                continue;
            }
            // Outcodes: bits 0-5 outside the frustum (near, far, sides) for trivial
            // rejection, bits 6-10 outside the near plane or the guard band (clip needed).
            let code = |v: Vec4| {
                let (gx, gy) = (self.guard_x * v.w, self.guard_y * v.w);
                u32::from(v.z < 0.0)
                    | u32::from(v.z > v.w) << 1
                    | u32::from(v.x > v.w) << 2
                    | u32::from(v.x < -v.w) << 3
                    | u32::from(v.y > v.w) << 4
                    | u32::from(v.y < -v.w) << 5
                    | u32::from(v.x > gx) << 6
                    | u32::from(v.x < -gx) << 7
                    | u32::from(v.y > gy) << 8
                    | u32::from(v.y < -gy) << 9
            };
            let codes = c.map(code);
            if codes[0] & codes[1] & codes[2] & 0x3f != 0 {
                continue;
            }
            let needs_clip = (codes[0] | codes[1] | codes[2]) & 0x3c1 != 0;
            let planes = [
                Plane::Near,
                Plane::Guard {
                    axis: 0,
                    sign: 1.0,
                    g: self.guard_x,
                },
                Plane::Guard {
                    axis: 0,
                    sign: -1.0,
                    g: self.guard_x,
                },
                Plane::Guard {
                    axis: 1,
                    sign: 1.0,
                    g: self.guard_y,
                },
                Plane::Guard {
                    axis: 1,
                    sign: -1.0,
                    g: self.guard_y,
                },
            ];
            if !needs_clip {
                self.emit(&mut chunk, local as u32, &p, [c[0], c[1], c[2]], None);
                continue;
            }
            poly.clear();
            for (k, &v) in c.iter().enumerate() {
                let mut bary = Vec3::ZERO;
                bary[k] = 1.0;
                poly.push(ClipVertex { clip: v, bary });
            }
            for &pl in &planes {
                if poly.iter().any(|v| pl.dist(v.clip) < 0.0) {
                    clip_polygon(&poly, pl, &mut tmp);
                    std::mem::swap(&mut poly, &mut tmp);
                    if poly.len() < 3 {
                        break;
                    }
                }
            }
            for k in 1..poly.len().saturating_sub(1) {
                let (a, b, d) = (poly[0], poly[k], poly[k + 1]);
                self.emit(
                    &mut chunk,
                    local as u32,
                    &p,
                    [a.clip, b.clip, d.clip],
                    Some([a.bary, b.bary, d.bary]),
                );
            }
        }
        self.bin(&mut chunk);
        chunk
    }

    /// Whether the box `lo..hi` lies wholly outside one plane of the frustum (near, far or a
    /// side), by a margin of 1e-4 of its corners' clip coordinates, so that no vertex
    /// inside it can pass the outcode test through rounding.
    fn box_outside(&self, lo: Vec3, hi: Vec3) -> bool {
        let corners = (0..8).map(|k| {
            let p = Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            self.view_proj * p.extend(1.0)
        });
        let mut all = [true; 6];
        for c in corners {
            if !c.is_finite() {
                return false;
            }
            let m = 1e-4 * (c.x.abs() + c.y.abs() + c.z.abs() + c.w.abs());
            let out = [
                c.z < -m,
                c.z - c.w > m,
                c.x - c.w > m,
                c.x + c.w < -m,
                c.y - c.w > m,
                c.y + c.w < -m,
            ];
            for (a, o) in all.iter_mut().zip(out) {
                *a &= o;
            }
        }
        all.iter().any(|&a| a)
    }

    /// Projects, snaps and bounds one (possibly clipped) triangle; drops it when it has no
    /// area or covers no pixel centre.
    fn emit(
        &self,
        chunk: &mut Chunk,
        local: u32,
        p: &[Vec3; 3],
        c: [Vec4; 3],
        bary: Option<[Vec3; 3]>,
    ) {
        let (w, h) = (self.width as f64, self.height as f64);
        let mut xy = [[0i32; 2]; 3];
        let mut z = [0f32; 3];
        for k in 0..3 {
            let iw = 1.0 / c[k].w as f64;
            let sx = (c[k].x as f64 * iw * 0.5 + 0.5) * w;
            let sy = (0.5 - c[k].y as f64 * iw * 0.5) * h;
            if !(sx.abs() < 2.0 * GUARD_PIXELS as f64 && sy.abs() < 2.0 * GUARD_PIXELS as f64) {
                return; // only reachable through w ~ 0 from rounding; nothing to draw
            }
            xy[k] = [snap(sx), snap(sy)];
            z[k] = (c[k].z as f64 * iw) as f32;
        }
        let mut c = c;
        let area = Edge::new(xy[0], xy[1]).at(xy[2][0] as i64, xy[2][1] as i64);
        if area == 0 {
            return;
        }
        let swapped = area < 0;
        if swapped {
            xy.swap(1, 2);
            z.swap(1, 2);
            c.swap(1, 2);
        }
        let min_x = xy.iter().map(|p| p[0]).min().unwrap_or(0) as i64;
        let max_x = xy.iter().map(|p| p[0]).max().unwrap_or(0) as i64;
        let min_y = xy.iter().map(|p| p[1]).min().unwrap_or(0) as i64;
        let max_y = xy.iter().map(|p| p[1]).max().unwrap_or(0) as i64;
        // Pixels whose centre x * 256 + 128 lies in [min, max].
        let first = |lo: i64| -((-(lo - HALF)).div_euclid(SUB));
        let last = |hi: i64| (hi - HALF).div_euclid(SUB);
        let x0 = first(min_x).max(0);
        let x1 = last(max_x).min(self.width as i64 - 1);
        let y0 = first(min_y).max(0);
        let y1 = last(max_y).min(self.height as i64 - 1);
        if x0 > x1 || y0 > y1 {
            return;
        }
        // Only now the interpolation planes: most triangles of a fine mesh in a small
        // target cover no pixel centre and are dropped above.
        let h = c.map(|v| glam::DVec3::new(v.x as f64, v.y as f64, v.w as f64));
        let plane = [h[1].cross(h[2]), h[2].cross(h[0]), h[0].cross(h[1])].map(|p| p.as_vec3());
        let view = &self.view;
        let code = match bary {
            None if swapped => BARY_SWAPPED,
            None => BARY_IDENTITY,
            Some(mut rows) => {
                if swapped {
                    rows.swap(1, 2);
                }
                chunk.barys.push(rows);
                (chunk.barys.len() - 1) as u32
            }
        };
        chunk.tris.push(Tri {
            xy,
            z,
            plane,
            depth: p.map(|p| (p - view.eye).dot(view.forward) / view.far),
            local,
            flip: facing_away(view, (p[1] - p[0]).cross(p[2] - p[0]), p[0]),
            bary: code,
            bbox: [x0 as u16, y0 as u16, x1 as u16, y1 as u16],
        });
    }

    /// Counting sort of the chunk's triangles into tiles (keeping triangle order).
    fn bin(&self, chunk: &mut Chunk) {
        let tile_range = |t: &Tri| {
            let b = t.bbox.map(|v| v as u32 / TILE);
            (b[0], b[1], b[2], b[3])
        };
        let mut counts = vec![0u32; self.tiles + 1];
        for t in &chunk.tris {
            let (tx0, ty0, tx1, ty1) = tile_range(t);
            for ty in ty0..=ty1 {
                for tx in tx0..=tx1 {
                    counts[(ty * self.tiles_x + tx) as usize + 1] += 1;
                }
            }
        }
        for i in 1..counts.len() {
            counts[i] += counts[i - 1];
        }
        let mut fill = counts.clone();
        let mut bins = vec![0u32; counts[self.tiles] as usize];
        for (i, t) in chunk.tris.iter().enumerate() {
            let (tx0, ty0, tx1, ty1) = tile_range(t);
            for ty in ty0..=ty1 {
                for tx in tx0..=tx1 {
                    let slot = &mut fill[(ty * self.tiles_x + tx) as usize];
                    bins[*slot as usize] = i as u32;
                    *slot += 1;
                }
            }
        }
        chunk.bin_start = counts;
        chunk.bins = bins;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene_core::builtin;

    /// A prepared scene skips the spans outside the frustum, and its G-buffer is the one
    /// drawn without skipping, bit for bit, from views that cull most and least.
    #[test]
    fn culled_spans_give_the_unculled_gbuffer() {
        // The building: 12 rooms in spans of 256 triangles, most outside a room's view.
        let scene = Arc::new(builtin::scene("building").unwrap());
        let mut prepared = CpuRasterizer::new();
        prepared.prepare(scene.clone()).unwrap();
        let bounds = prepared.bounds.clone().unwrap();
        for camera in &scene.cameras {
            let view = View::from_camera(&camera.with_aspect(4.0 / 3.0));
            let ctx = SetupContext::new(&view, 96, 72);
            let spans: Vec<_> = bounds.meshes.iter().flatten().flatten().collect();
            let culled = spans
                .iter()
                .filter(|(lo, hi)| ctx.box_outside(*lo, *hi))
                .count();
            assert!(
                culled > 0 && culled < spans.len(),
                "{}: {culled} of {}",
                camera.name,
                spans.len()
            );
            let a = prepared
                .render_views(&[ViewTarget::new(view, 96, 72)])
                .unwrap();
            let b = CpuRasterizer::new()
                .render_gbuffer(&scene, &view, 96, 72)
                .unwrap();
            assert!(a[0] == b, "{}: the culled G-buffer differs", camera.name);
        }
    }
}
