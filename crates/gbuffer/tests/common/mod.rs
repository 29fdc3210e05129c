//! Helpers shared by the integration tests.
#![allow(dead_code)]

use scene_core::glam::{Vec2, Vec3};
use scene_core::{GBuffer, Material, Mesh, Scene, Texture, View};

/// Where two G-buffers of the same size disagree, and by how much where they agree.
#[derive(Debug, Default)]
pub struct Diff {
    pub pixels: usize,
    pub id_equal: usize,
    /// Differing pixels that do not lie on a triangle edge in either buffer.
    pub off_edge: Vec<(u32, u32)>,
    pub max_depth: f32,
    pub max_normal: f32,
    pub max_albedo: f32,
}

impl Diff {
    pub fn id_fraction(&self) -> f64 {
        self.id_equal as f64 / self.pixels.max(1) as f64
    }
}

/// True when pixel `(x, y)` of `g` has a 3x3 neighbour with another triangle id.
pub fn on_edge(g: &GBuffer, x: u32, y: u32) -> bool {
    let id = g.triangle_id[(y * g.width + x) as usize];
    for dy in -1i32..=1 {
        for dx in -1i32..=1 {
            let (nx, ny) = (x as i32 + dx, y as i32 + dy);
            if nx < 0 || ny < 0 || nx >= g.width as i32 || ny >= g.height as i32 {
                continue;
            }
            if g.triangle_id[(ny as u32 * g.width + nx as u32) as usize] != id {
                return true;
            }
        }
    }
    false
}

pub fn diff(a: &GBuffer, b: &GBuffer) -> Diff {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let mut d = Diff {
        pixels: a.len(),
        ..Default::default()
    };
    for i in 0..a.len() {
        let (x, y) = (i as u32 % a.width, i as u32 / a.width);
        if a.triangle_id[i] != b.triangle_id[i] {
            if !on_edge(a, x, y) && !on_edge(b, x, y) {
                d.off_edge.push((x, y));
            }
            continue;
        }
        d.id_equal += 1;
        d.max_depth = d.max_depth.max((a.depth[i] - b.depth[i]).abs());
        d.max_normal = d
            .max_normal
            .max((a.normal[i] - b.normal[i]).abs().max_element());
        d.max_albedo = d
            .max_albedo
            .max((a.albedo[i] - b.albedo[i]).abs().max_element());
    }
    d
}

/// Checks the invariants every G-buffer of this crate must satisfy: finite values, unit
/// normals on geometry, on the viewer's side of their triangle (whose geometric normal,
/// flipped to face the eye, faces the eye), depth in (0, 1], background values elsewhere.
pub fn check_invariants(g: &GBuffer, view: &View, scene: &Scene) {
    let fr = gbuffer::FrustumReconstruction::new(view);
    let offsets = scene.mesh_offsets();
    for i in 0..g.len() {
        let (x, y) = (i as u32 % g.width, i as u32 / g.width);
        assert!(g.albedo[i].is_finite() && g.normal[i].is_finite() && g.depth[i].is_finite());
        if g.is_background(i) {
            assert_eq!(g.depth[i], 1.0, "background depth at ({x}, {y})");
            assert_eq!(g.normal[i], Vec3::ZERO);
            assert_eq!(g.albedo[i].w, 0.0);
            continue;
        }
        assert_eq!(g.albedo[i].w, 1.0, "radiation mask at ({x}, {y})");
        assert!(
            (g.normal[i].length() - 1.0).abs() < 1e-4,
            "normal {} at ({x}, {y})",
            g.normal[i]
        );
        assert!(
            g.depth[i] > 0.0 && g.depth[i] <= 1.0,
            "depth {} at ({x}, {y})",
            g.depth[i]
        );
        let uv = Vec2::new(
            (x as f32 + 0.5) / g.width as f32,
            (y as f32 + 0.5) / g.height as f32,
        );
        let p = fr.world(uv, g.depth[i]);
        let to_eye = match view.projection {
            scene_core::Projection::Perspective { .. } => view.eye - p,
            scene_core::Projection::Orthographic { .. } => -view.forward,
        };
        let r = scene.triangle_ref(&offsets, g.triangle_id[i]).unwrap();
        let mesh = &scene.meshes[r.mesh as usize];
        let t = mesh.indices[r.local as usize].map(|k| mesh.positions[k as usize]);
        let mut ng = (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero();
        if ng.dot(to_eye) < 0.0 {
            ng = -ng;
        }
        assert!(
            g.normal[i].dot(ng) > 0.0,
            "normal {} on the far side of its triangle ({ng}) at ({x}, {y})",
            g.normal[i]
        );
    }
}

/// A scene of one mesh with a grey material.
pub fn one_mesh_scene(name: &str, mesh: Mesh) -> Scene {
    let mut s = Scene::new(name);
    s.materials
        .push(Material::diffuse("grey", Vec3::splat(0.5)));
    s.meshes.push(mesh);
    s
}

/// A unit-spaced grid of `n x n` quads in the plane z = `z` over `[x0, x0 + n step]^2`,
/// jittered interior vertices (deterministic), every other triangle wound the other way.
pub fn grid_mesh(n: u32, x0: f32, step: f32, z: f32, jitter: f32) -> Mesh {
    let mut m = Mesh {
        name: "grid".into(),
        ..Default::default()
    };
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut rnd = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    };
    for j in 0..=n {
        for i in 0..=n {
            let interior = i > 0 && j > 0 && i < n && j < n;
            let (jx, jy) = if interior {
                (rnd() * jitter * step, rnd() * jitter * step)
            } else {
                (0.0, 0.0)
            };
            m.positions.push(Vec3::new(
                x0 + i as f32 * step + jx,
                x0 + j as f32 * step + jy,
                z,
            ));
            m.normals.push(Vec3::Z);
        }
    }
    let at = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            // Alternate the diagonal and the winding.
            let (t1, t2) = if (i + j) % 2 == 0 {
                ([a, b, c], [a, c, d])
            } else {
                ([b, c, d], [b, a, d])
            };
            m.indices.push(t1);
            m.indices.push(t2);
            m.material_ids.extend([0, 0]);
        }
    }
    m
}

/// A scene with one textured quad (a 4x4 checker of colours) facing +z in [-1, 1]^2.
pub fn textured_quad_scene() -> Scene {
    let mut s = Scene::new("textured");
    let mut mat = Material::diffuse("checker", Vec3::new(0.9, 0.8, 0.7));
    mat.albedo_texture = Some(0);
    s.materials.push(mat);
    let texels = (0..16)
        .map(|i| {
            let (x, y) = (i % 4, i / 4);
            if (x + y) % 2 == 0 {
                Vec3::new(0.9, 0.2, 0.1)
            } else {
                Vec3::new(0.1, 0.3, 0.8 - 0.1 * y as f32)
            }
        })
        .collect();
    s.textures.push(Texture {
        name: "checker".into(),
        width: 4,
        height: 4,
        texels,
        alpha: None,
        sampler: Default::default(),
    });
    let mut m = Mesh {
        name: "quad".into(),
        uvs: Some(Vec::new()),
        ..Default::default()
    };
    m.push_quad(
        [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ],
        0,
    );
    // Scale the UVs so the texture repeats twice (tests wrapping).
    if let Some(uvs) = &mut m.uvs {
        for uv in uvs.iter_mut() {
            *uv *= 2.0;
        }
    }
    s.meshes.push(m);
    s
}

/// A perspective view at `eye` looking at `target` (+Y up unless looking along Y).
pub fn look_at(eye: Vec3, target: Vec3, fov_deg: f32, aspect: f32, near: f32, far: f32) -> View {
    let cam = scene_core::Camera {
        name: "test".into(),
        position: eye,
        target,
        up: if (target - eye).normalize().y.abs() > 0.99 {
            Vec3::Z
        } else {
            Vec3::Y
        },
        fov_y: fov_deg.to_radians(),
        aspect,
        near,
        far,
    };
    View::from_camera(&cam)
}
